"""What every sans-I/O device codec shares: the decoder's counters and its contract.

A decoder is fed bytes as they arrive (any split, any garbage) and returns the
typed records completed by them.  It never blocks, never sleeps and never raises
on bad bytes: it counts what it skipped and resynchronises (the h11/wsproto
pattern).  Time stamps are the caller's: ``feed(data, t)`` stamps every record
completed by ``data`` with ``t``, the arrival time of those bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol


@dataclass(slots=True)
class DecodeStats:
    """Counters every decoder keeps; health reports them."""

    bytes_in: int = 0
    records: int = 0
    skipped_bytes: int = 0  # garbage and the bytes of rejected frames
    bad_checksum: int = 0
    bad_frame: int = 0  # well delimited but unparseable or out of range
    reasons: dict[str, int] = field(default_factory=dict)

    def bad(self, reason: str) -> None:
        """A well-framed record whose content is unusable (NaN, out of range)."""
        self.bad_frame += 1
        self.reasons[reason] = self.reasons.get(reason, 0) + 1

    def skip(self, n: int, reason: str) -> None:
        self.skipped_bytes += n
        self.reasons[reason] = self.reasons.get(reason, 0) + 1

    def too_long(self, n: int) -> None:
        """A line past the longest a device sends: garbage or binary, skipped."""
        self.skip(n, "too_long")
        self.bad_frame += 1


@dataclass(frozen=True, slots=True)
class DeviceError:
    """The device answered, but with an error in place of a reading.

    Not a measurement: the daemon counts it apart and shows ``what`` in health.
    ``code`` is the device's own (an exception code, a status byte, a register);
    ``send`` is what the device needs to be told to recover, if anything (sans-I/O:
    the decoder says it, the daemon writes it).
    """

    t: float
    code: int
    what: str
    send: bytes = b""


class FrameDecoder:
    """Binary frames whose first bytes give their length, closed by a checksum.

    The framing every binary device here shares (Keller bus, 3DM-GX3): find a
    plausible frame start, wait for the whole frame, check it, and on a mismatch
    slide by one byte, because a real frame may begin inside the rejected one.
    Subclasses say where frames start, how long they are, what checks them and
    what they mean.
    """

    def __init__(self) -> None:
        self.stats = DecodeStats()
        self._buf = bytearray()

    def _frame_length(self, buf: bytearray) -> int | None:
        """Length of the frame starting at ``buf[0]``, 0 if more bytes are needed to
        tell, None if no frame starts there."""
        raise NotImplementedError

    def _checksum_ok(self, frame: bytes) -> bool:
        raise NotImplementedError

    def _parse(self, frame: bytes, t: float) -> object | None:
        """The record a checked frame holds, or None (after counting why) if unusable."""
        raise NotImplementedError

    def reset(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        buf = self._buf
        buf += data
        out: list[object] = []
        while buf:
            n = self._frame_length(buf)
            if n is None:
                self.stats.skip(1, "resync")
                del buf[0]
                continue
            if n == 0 or len(buf) < n:
                break  # wait for the rest of the frame
            frame = bytes(buf[:n])
            if not self._checksum_ok(frame):
                self.stats.bad_checksum += 1
                self.stats.skip(1, "checksum")
                del buf[0]
                continue
            del buf[:n]
            rec = self._parse(frame, t)
            if rec is not None:
                out.append(rec)
                self.stats.records += 1
        return out


class Decoder(Protocol):
    stats: DecodeStats

    def feed(self, data: bytes, t: float) -> list[object]: ...

    def reset(self) -> None:
        """Forget any partial frame (the counters stay)."""


def feed_guarded(
    decoder: Decoder, data: bytes, t: float, on_error: Callable[[Exception], None]
) -> list[object]:
    """``decoder.feed`` that a decoder bug cannot make lose a read's other records.

    Decoders never raise by contract; this is the defence in depth behind it.  If
    ``feed`` raises, the partial frame is dropped and the same bytes are fed again
    one at a time, skipping only where it raises again, so the records before and
    after the fault are still delivered.
    """
    try:
        return decoder.feed(data, t)
    except Exception as exc:
        on_error(exc)
    decoder.reset()
    refeed = getattr(decoder, "refeed", decoder.feed)  # a logging wrapper logs once
    out: list[object] = []
    for i in range(len(data)):
        try:
            out += refeed(data[i : i + 1], t)
        except Exception as exc:
            on_error(exc)
            decoder.reset()
    return out
