"""Device codecs: golden byte vectors (with the document they come from), fuzzing, resync.

The protocol sources are listed in docs/protocols.md.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from navd.drivers import ahrs, castle, gps, gpsd, keller, modem
from navd.records import Attitude, Gps, Pressure, Rpm

# -- golden vectors -------------------------------------------------------------------
# Keller bus protocol ("Communication protocol Serie 30", F48 example): initialise the
# device at address 250 is FA 30 04 43 -- CRC-16/MODBUS, high byte first.
KELLER_INIT_250 = bytes.fromhex("fa 30 04 43")
# F73 channel 1 (P1) to address 250, and an answer of 1.5 bar with status 0.
KELLER_READ_P1 = bytes.fromhex("fa 49 01 a1 a7")
KELLER_P1_1_5_BAR = bytes.fromhex("fa 49 3f c0 00 00 00 53 67")
# 3DM-GX3-25 single-byte protocol, 0xCE Euler angles: roll 10 deg, pitch -5 deg,
# yaw -90 deg (radians, big-endian floats), timer 62500 ticks (1 s), checksum 0x092B.
AHRS_EULER = bytes.fromhex("ce 3e 32 b8 c2 bd b2 b8 c2 bf c9 0f db 00 00 f4 24 09 2b")
# NMEA 0183: the standard's textbook GGA and RMC examples (Munich, 23 March 1994).
NMEA_GGA = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
NMEA_RMC = b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n"
NMEA_NO_FIX = b"$GPGGA,000000.00,,,,,0,00,99.9,,M,,M,,*5F\r\n"
# Castle Serial Link v1.5: device 0 reads register 5 (speed); an answer of raw 1000 (0x03E8).
CASTLE_READ_SPEED = bytes.fromhex("80 05 00 00 7b")
CASTLE_RAW_1000 = bytes.fromhex("03 e8 15")
# the range line as the Goby3 ATM-900 driver reads it; the location line is navd's reading
MODEM_ATRX = (
    b"Range 1 to 2 : 153.4 m  (Round-trip  204.5 ms) speed  0.0 m/s\r\n"
    b"Remote Lat: 37.0490112 Lon: -80.6670001 Depth: 3.0\r\nOK\r\n"
)


def test_keller_crc_is_crc16_modbus() -> None:
    assert keller.crc16(b"123456789") == 0x4B37  # the CRC catalogue's check value


def test_keller_golden() -> None:
    assert keller.encode_init(250) == KELLER_INIT_250
    d = keller.KellerDecoder(250)
    assert d.request(keller.CH_PRESSURE) == KELLER_READ_P1
    (rec,) = d.feed(KELLER_P1_1_5_BAR, 7.0)
    assert rec == Pressure(7.0, 1.5)


def test_ahrs_golden() -> None:
    (rec,) = ahrs.AhrsDecoder().feed(AHRS_EULER, 3.0)
    assert rec.timer_s == pytest.approx(1.0)
    att: Attitude = rec.attitude
    assert att.roll_deg == pytest.approx(10.0, abs=1e-4)
    assert att.pitch_deg == pytest.approx(-5.0, abs=1e-4)
    assert att.yaw_deg == pytest.approx(270.0, abs=1e-4)  # -90 deg as a compass heading
    assert ahrs.encode_continuous() == bytes.fromhex("c4 c1 29 ce")
    assert ahrs.encode_stop() == bytes.fromhex("fa 75 b4")
    assert len(ahrs.encode_sampling(50.0)) == 20


def test_nmea_golden() -> None:
    d = gps.NmeaDecoder()
    fix, when = d.feed(NMEA_GGA + NMEA_RMC, 1.0)
    assert fix.lat == pytest.approx(48.1173) and fix.lon == pytest.approx(11.516667, abs=1e-6)
    assert fix.alt == pytest.approx(545.4 + 46.9)  # ellipsoidal: MSL plus geoid separation
    assert fix.fix == 1 and fix.hdop == pytest.approx(0.9)
    assert when.valid and when.utc.isoformat() == "1994-03-23T12:35:19+00:00"
    (nofix,) = d.feed(NMEA_NO_FIX, 2.0)
    assert nofix == Gps(2.0, None, None, None, 0, 99.9, 0, sats=0)


def test_castle_golden() -> None:
    d = castle.CastleDecoder(pole_pairs=1)
    assert d.request_rpm() == CASTLE_READ_SPEED
    (rec,) = d.feed(CASTLE_RAW_1000, 4.0)
    assert isinstance(rec, Rpm)
    assert rec.rpm == pytest.approx(1000 / 2042 * 20416.66)


def test_modem_golden() -> None:
    assert modem.encode_range(2) == b"ATRX2\r"
    d = modem.ModemDecoder()
    rng, ok = d.feed(MODEM_ATRX, 12.5)
    assert rng == modem.ModemRange(12.5, 153.4, 2, 37.0490112, -80.6670001, 3.0, 0.2045, 0.0)
    assert ok == modem.ModemReply(12.5, "ok")
    (lost,) = d.feed(b"Response Not Received.\r\n", 20.0)
    assert lost.status == "no_reply"
    # a garbled location keeps the range and drops the position
    out = d.feed(b"Range 1 to 2 : 99.0 m\r\nRemote Lat: 3704.90112 Lon: -80.66 Depth: 3\r\n", 30)
    assert out[0].range_m == 99.0 and out[0].lat is None and out[0].lon == -80.66


# -- fuzzing: random, truncated and spliced input -------------------------------------
BINARY = [
    (lambda: keller.KellerDecoder(250), KELLER_P1_1_5_BAR, "request"),
    (ahrs.AhrsDecoder, AHRS_EULER, None),
    (lambda: castle.CastleDecoder(), CASTLE_RAW_1000, "request_rpm"),
]


def _prime(dec, how: str | None, n: int) -> None:
    for _ in range(n):
        if how == "request":
            dec.request(keller.CH_PRESSURE)
        elif how == "request_rpm":
            dec.request_rpm()


@pytest.mark.parametrize("make,frame,how", BINARY)
@given(garbage=st.binary(max_size=60), cut=st.integers(0, 40), chunk=st.integers(1, 7))
@settings(max_examples=150, deadline=None)
def test_binary_decoders_resync_and_count_every_byte(make, frame, how, garbage, cut, chunk):
    dec = make()
    # garbage, a truncated frame, then two good frames, fed in arbitrary chunks
    stream = garbage + frame[: cut % len(frame)] + frame + frame
    _prime(dec, how, 8)
    recs = []
    for i in range(0, len(stream), chunk):
        recs += dec.feed(stream[i : i + chunk], 0.0)
    assert len(recs) >= 1  # the last good frame is always found
    s = dec.stats
    assert s.bytes_in == len(stream)
    assert s.skipped_bytes + s.records * len(frame) + len(dec._buf) == len(stream)


@pytest.mark.parametrize(
    "make",
    [
        gps.NmeaDecoder,
        gpsd.GpsdDecoder,
        modem.ModemDecoder,
        ahrs.AhrsDecoder,
        castle.CastleDecoder,
        lambda: keller.KellerDecoder(250),
    ],
)
@given(data=st.lists(st.binary(max_size=50), max_size=20))
@settings(max_examples=150, deadline=None)
def test_decoders_never_raise_on_random_input(make, data) -> None:
    dec = make()
    for chunk in data:
        for rec in dec.feed(chunk, 1.0):
            for v in getattr(rec, "__slots__", ()):
                x = getattr(rec, v)
                assert not (isinstance(x, float) and not math.isfinite(x))


@given(
    garbage=st.binary(max_size=80).filter(lambda b: not set(b) & set(b"$\r\n")),
    chunk=st.integers(1, 9),
)
@settings(max_examples=150, deadline=None)
def test_nmea_resyncs_after_garbage_and_counts_it(garbage: bytes, chunk: int) -> None:
    dec = gps.NmeaDecoder()
    bad = NMEA_GGA.replace(b"*47", b"*48")
    stream = garbage + NMEA_GGA[:20] + bad + NMEA_GGA
    recs = []
    for i in range(0, len(stream), chunk):
        recs += dec.feed(stream[i : i + chunk], 0.0)
    assert [r.lat for r in recs] == [pytest.approx(48.1173)]
    assert dec.stats.bad_checksum == 1
    # line ends are not garbage: the bad sentence costs its bytes up to its CR
    assert dec.stats.skipped_bytes == len(garbage) + 20 + len(bad) - 2


@given(garbage=st.binary(max_size=80).filter(lambda b: b"\r" not in b and b"\n" not in b))
@settings(max_examples=100, deadline=None)
def test_modem_resyncs_after_garbage(garbage: bytes) -> None:
    dec = modem.ModemDecoder()
    recs = dec.feed(garbage + b"\r\n" + MODEM_ATRX, 0.0)
    ranges = [r for r in recs if isinstance(r, modem.ModemRange)]
    assert ranges[-1].range_m == 153.4 and ranges[-1].lat == 37.0490112


# -- the emulators produce the same golden bytes ----------------------------------------
def test_emulators_speak_the_golden_vectors(tmp_path) -> None:
    import asyncio

    from navd.hil.emulators import ahrs as ahrs_emu
    from navd.hil.emulators import castle as castle_emu
    from navd.hil.emulators import gps as gps_emu
    from navd.hil.emulators import keller as keller_emu
    from navd.hil.emulators import modem as modem_emu

    assert keller_emu._crc(b"\xfa\x30") == KELLER_INIT_250[2:]
    assert gps_emu.sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") == (
        NMEA_GGA
    )

    async def main() -> None:
        sent: list[bytes] = []
        k = keller_emu.KellerEmulator(tmp_path / "k", addr=250)
        k.pressure_bar = 1.5
        k.send = sent.append  # capture what goes on the line
        k.on_bytes(KELLER_READ_P1)
        await asyncio.sleep(0.05)
        assert sent == [KELLER_P1_1_5_BAR]

        a = ahrs_emu.AhrsEmulator(tmp_path / "a")
        a.roll_deg, a.pitch_deg, a.yaw_deg = 10.0, -5.0, 270.0
        a._timer = lambda: 62500
        assert a.euler_frame() == AHRS_EULER

        sent.clear()
        c = castle_emu.CastleEmulator(tmp_path / "c")
        c.rpm = 1000 * 20416.66 / 2042
        c.send = sent.append
        c.on_bytes(CASTLE_READ_SPEED)
        await asyncio.sleep(0.05)
        assert sent == [CASTLE_RAW_1000]

        sent.clear()
        m = modem_emu.ModemEmulator(
            tmp_path / "m", lambda t: (0.2045, 153.4, 37.0490112, -80.6670001, 3.0), online=False
        )
        m.send = sent.append
        m.on_bytes(b"ATRX2\r")
        await asyncio.sleep(0.35)
        assert sent == [MODEM_ATRX]
        for e in (k, a, c, m):
            e.close()

    asyncio.run(main())


def test_castle_slides_over_a_window_that_passes_the_check_by_chance() -> None:
    """Headerless 3-byte answers: garbage + a cut answer can sum to zero mod 256.

    Found by the fuzz test: ``fa 03 | 03 e8 15`` gives the window ``fa 03 03``, whose
    check passes and whose value no motor reaches; it must not eat the request.
    """
    dec = castle.CastleDecoder()
    dec.request_rpm()
    recs = dec.feed(bytes.fromhex("fa0303e815"), 1.0)
    assert [round(r.rpm) for r in recs] == [round(1000 / 2042.0 * 20416.66)]
    st = dec.stats
    assert st.bad_frame == 1 and st.skipped_bytes == 2 and st.bytes_in == 5


# -- every decoder over real sentences interleaved with garbage, split anywhere ----------
_CORPUS = Path(__file__).parent / "data" / "gpsd"
_REAL_NMEA = [
    ln + b"\r\n"
    for p in sorted(_CORPUS.glob("*.log"))
    for ln in p.read_bytes().splitlines()
    if ln.startswith(b"$")
][::7]
_REAL_GPSD = [
    ln + b"\n" for p in sorted(_CORPUS.glob("*.chk")) for ln in p.read_bytes().splitlines()
][::11]
_REAL = {
    "nmea": (gps.NmeaDecoder, _REAL_NMEA),
    "gpsd": (gpsd.GpsdDecoder, _REAL_GPSD),
    "ahrs": (ahrs.AhrsDecoder, [AHRS_EULER]),
    "keller": (keller.KellerDecoder, [KELLER_P1_1_5_BAR]),
    "modem": (modem.ModemDecoder, [MODEM_ATRX, b"Response Not Received.\r\n"]),
    "castle": (castle.CastleDecoder, [CASTLE_RAW_1000]),
}


def _feed_all(dec, stream: bytes, cuts: list[int]) -> list[object]:
    out: list[object] = []
    edges = [0, *sorted({c % (len(stream) + 1) for c in cuts}), len(stream)]
    for a, b in itertools.pairwise(edges):
        out += dec.feed(stream[a:b], 1.0)
    return out


@pytest.mark.parametrize("name", sorted(_REAL))
@given(data=st.data())
@settings(max_examples=120, deadline=None)
def test_every_decoder_is_total_and_split_invariant_over_real_bytes(name: str, data) -> None:
    make, real = _REAL[name]
    parts = data.draw(
        st.lists(st.one_of(st.sampled_from(real), st.binary(max_size=40)), max_size=25)
    )
    stream = b"".join(parts)
    cuts = data.draw(st.lists(st.integers(0, 10_000), max_size=12))
    whole = make().feed(stream, 1.0)
    assert _feed_all(make(), stream, cuts) == whole
