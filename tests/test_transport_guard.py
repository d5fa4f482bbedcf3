"""Defence in depth: a decoder that raises never costs the other records of its read."""

from __future__ import annotations

from navd.drivers.codec import DecodeStats, feed_guarded
from navd.drivers.gps import NmeaDecoder
from navd.records import Gps

GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
GGA2 = b"$GPGGA,123520,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*4D\r\n"


class _Buggy(NmeaDecoder):
    """A decoder with a bug: a sentence naming BUG makes it raise."""

    def _sentence(self, line: bytes, t: float) -> object | None:
        if b"BUG" in line:
            raise AttributeError("a decoder bug")
        return super()._sentence(line, t)


def test_records_before_and_after_a_raising_sentence_are_delivered() -> None:
    dec = _Buggy()
    errors: list[Exception] = []
    recs = feed_guarded(dec, GGA + b"$PBUG,1*00\r\n" + GGA2, 0.0, errors.append)
    assert [r.lat for r in recs if isinstance(r, Gps)] == [48.1173, 48.1173]
    assert len(errors) >= 2 and all(isinstance(e, AttributeError) for e in errors)
    # the decoder goes on: the next read is decoded as usual
    assert len(feed_guarded(dec, GGA.replace(b"123519", b"123521").replace(b"*47", b"*4C"),
                            1.0, errors.append)) == 1


def test_a_decoder_that_does_not_raise_is_fed_once() -> None:
    class Counting:
        def __init__(self) -> None:
            self.stats = DecodeStats()
            self.calls = 0

        def feed(self, data: bytes, t: float) -> list[object]:
            self.calls += 1
            return [data]

        def reset(self) -> None:
            raise AssertionError("not reset")

    dec = Counting()
    assert feed_guarded(dec, b"abc", 0.0, lambda e: None) == [b"abc"] and dec.calls == 1
