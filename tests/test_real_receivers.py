"""The GPS decoder over real receivers' bytes: gpsd's regression captures (tests/data/gpsd).

What users rely on: whatever a receiver interleaves (proprietary sentences, binary,
stray CRs, a second talker per epoch), every fix it gives reaches the filter once, at
any read size, at the position gpsd decodes, with the height for what it is.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
from conftest import DeviceHost

from navd.drivers.gps import NmeaDecoder
from navd.records import Gps

CORPUS = sorted((Path(__file__).parent / "data" / "gpsd").glob("*.log"))
# a checksummed GGA with a fix quality 1..5 and a position: each must become a fix
_GGA = re.compile(rb"\$(?:GP|GN|GL|GA|GB|BD|IN)GGA,([^,*]*),\d+\.?\d*,[NS],\d+\.?\d*,[EW],[1-5],")


def _fixes(data: bytes, size: int) -> tuple[list[Gps], NmeaDecoder]:
    dec = NmeaDecoder()
    out: list[Gps] = []
    for i in range(0, len(data), size):
        out += [r for r in dec.feed(data[i : i + size], 0.0) if isinstance(r, Gps)]
    return out, dec


def _checksum_ok(line: bytes) -> bool:
    body, _, cs = line.strip().lstrip(b"$").partition(b"*")
    x = 0
    for c in body:
        x ^= c
    return cs[:2].upper() == f"{x:02X}".encode()


def _epochs_expected(data: bytes) -> int:
    """Distinct epochs of the usable GGAs, read with a regular expression (not the decoder)."""
    epochs: list[bytes] = []
    for line in re.split(rb"[\r\n]+", data):
        m = _GGA.search(line)
        if m and _checksum_ok(line[m.start() :]) and (not epochs or epochs[-1] != m.group(1)):
            epochs.append(m.group(1))
    return len(epochs)


def test_corpus_is_there():
    assert len(CORPUS) >= 20


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
@pytest.mark.parametrize("size", [1, 16, 256, 4096])
def test_no_exception_and_no_lost_fix_at_any_read_size(path: Path, size: int):
    data = path.read_bytes()
    whole, _ = _fixes(data, len(data))
    split, dec = _fixes(data, size)
    assert split == whole  # the same records whatever the split
    with_position = [r for r in split if r.lat is not None]
    assert len(with_position) == _epochs_expected(data)
    assert dec.stats.bytes_in == len(data)


def _tpv_by_time(path: Path) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    for line in (path.parent / (path.name + ".chk")).read_text().splitlines():
        o = json.loads(line)
        if "lat" in o and "time" in o:
            out.setdefault(o["time"][11:19], []).append(o)  # hh:mm:ss of gpsd's time
    return out


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
def test_positions_and_heights_match_gpsd(path: Path):
    tpv = _tpv_by_time(path)
    dec = NmeaDecoder()
    compared = 0
    for line in re.split(rb"(?<=\n)", path.read_bytes()):
        for rec in dec.feed(line, 0.0):
            if not isinstance(rec, Gps) or rec.lat is None or rec.lon is None:
                continue
            m = re.search(rb"GGA,(\d\d)(\d\d)(\d\d)(\.\d+)?,", line)
            assert m, line
            frac = float(m.group(4) or 0.0)
            same = [
                o
                for o in tpv.get(f"{m[1].decode()}:{m[2].decode()}:{m[3].decode()}", [])
                if abs(float(o["time"][19:-1] or 0.0) - frac) < 1e-3
            ]
            if not same:
                continue  # gpsd reported no position for this epoch (it waits for a date)
            o = min(same, key=lambda o: abs(o["lat"] - rec.lat) + abs(o["lon"] - rec.lon))
            assert abs(o["lat"] - rec.lat) < 1e-7 and abs(o["lon"] - rec.lon) < 1e-7, line
            if rec.geoid_sep is None:
                assert rec.alt is None  # an MSL height is never passed off as ellipsoidal
            elif "altHAE" in o:
                assert rec.alt == pytest.approx(o["altHAE"], abs=0.01)
            if rec.alt_msl is not None and "altMSL" in o:
                assert rec.alt_msl == pytest.approx(o["altMSL"], abs=0.01)
            compared += 1
    # tnt-revolution is a compass (no GGA fix); ericsson-gru04's one fix gpsd does not report
    assert compared > 0 or path.stem in ("tnt-revolution", "ericsson-gru04")


def test_proprietary_sentence_costs_nothing_of_its_read():
    gga = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
    glor = b"$PGLOR,1,FIX,1.0,1.0*20\r\n"
    dec = NmeaDecoder()
    recs = dec.feed(gga + glor + gga.replace(b"123519", b"123520").replace(b"*47", b"*4D"), 0.0)
    assert [type(r).__name__ for r in recs] == ["Gps", "Gps"]
    assert dec.stats.reasons["proprietary_PGLOR"] == 1


@pytest.mark.parametrize("end", [b"\r", b"\n", b"\r\n"])
def test_every_line_ending(end: bytes):
    gga = b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"
    dec = NmeaDecoder()
    recs = dec.feed((gga + end) * 3, 0.0)
    assert len(recs) == 1 and dec.stats.reasons == {"duplicate_epoch": 2}
    assert dec.stats.skipped_bytes == 0


@pytest.mark.parametrize(
    ("lat", "why"),
    [("3775.000", "minutes_out_of_range"), ("9100.000", "coordinate_out_of_range")],
)
def test_coordinates_out_of_their_range_are_refused(lat: str, why: str):
    body = f"GPGGA,123519,{lat},N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
    cs = 0
    for c in body.encode():
        cs ^= c
    dec = NmeaDecoder()
    assert dec.feed(f"${body}*{cs:02X}\r\n".encode(), 0.0) == []
    assert dec.stats.reasons == {why: 1}


def test_height_without_separation_is_msl_only():
    body = "GPGGA,204132.10,4205.733715,N,08802.040978,W,2,08,1.0,221.921,M,,,3,0138"
    cs = 0
    for c in body.encode():
        cs ^= c
    (rec,) = NmeaDecoder().feed(f"${body}*{cs:02X}\r\n".encode(), 0.0)
    assert isinstance(rec, Gps)
    assert rec.alt is None and rec.alt_msl == pytest.approx(221.921) and rec.geoid_sep is None


def test_a_fix_naming_no_satellite_and_no_hdop_is_not_full_weight():
    from navd.filter.gpsfix import fix_std

    dec = NmeaDecoder()
    (rec,) = dec.feed(b"$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A\r\n", 0.0)
    assert isinstance(rec, Gps) and rec.sats == 0 and rec.hdop is None  # Saab R4, as sent
    assert fix_std(3.0, rec.hdop, rec.quality, rec.sats, 10.0) == pytest.approx(30.0)
    assert fix_std(3.0, 1.3, 2, 0, 10.0) == pytest.approx(3.9)  # an HDOP says the geometry
    assert fix_std(3.0, None, 1, None, 10.0) == pytest.approx(3.0)  # a log without sats


def _receiver() -> tuple[DeviceHost, Any]:
    from navd.daemon.devices.gps import GpsReceiver
    from navd.settings import GpsDevice

    host = DeviceHost()
    return host, GpsReceiver(GpsDevice(port="/dev/null"), host)  # type: ignore[arg-type]


def test_what_the_receiver_says_beyond_fixes_is_counted_in_health():
    import time

    host, dev = _receiver()
    data = (Path(__file__).parent / "data" / "gpsd" / "sirfstarv-nmea.log").read_bytes()
    for rec in dev.decoder.feed(data, 0.0):
        dev.handle(rec)
    h = dev.health(time.monotonic())
    assert h.decode_reasons["duplicate_epoch"] == 59  # GL's GGA of each epoch
    assert sum(isinstance(r, Gps) and r.lat is not None for r in host.fed) == 59


def test_the_receiver_s_utc_reaches_the_navigator_once_a_minute():
    """A real receiver's valid RMCs give the tidal prediction's clock (navd/records.py,
    ``Clock``): at the first, as the sentence says it, and then once a minute."""
    import datetime as dt

    from navd.daemon.devices.gps import CLOCK_EVERY_S
    from navd.records import Clock

    host, dev = _receiver()
    lines = (Path(__file__).parent / "data" / "gpsd" / "sirfstarv-nmea.log").read_bytes()
    rmc = [ln for ln in lines.splitlines(keepends=True) if b"RMC," in ln]
    t = 0.0
    for _ in range(3):  # the capture's minute of sentences, three times over, 1 s apart
        for ln in rmc:
            t += 1.0
            for rec in dev.decoder.feed(ln, t):
                dev.handle(rec)
    clocks = [r for r in host.fed if isinstance(r, Clock)]
    first = dt.datetime(2019, 2, 5, 2, 9, 35, tzinfo=dt.UTC)  # its first RMC, status A
    assert clocks[0] == Clock(1.0, first.timestamp())
    assert len(clocks) == math.ceil(t / CLOCK_EVERY_S)
    assert all(b.t - a.t >= CLOCK_EVERY_S for a, b in zip(clocks, clocks[1:], strict=False))


def _times(dec: object, data: bytes, size: int) -> list[object]:
    from navd.drivers.gps import GpsTime

    out: list[object] = []
    for i in range(0, len(data), size):
        out += [r for r in dec.feed(data[i : i + size], 0.0) if isinstance(r, GpsTime)]  # type: ignore[attr-defined]
    return out


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
@pytest.mark.parametrize("size", [1, 16, 256, 4096])
def test_every_receiver_time_reaches_the_clock_at_any_read_size(path: Path, size: int):
    """The receivers' UTC, which the tidal prediction's clock is read from (navd/records.py,
    ``Clock``): every RMC's and every time gpsd decoded from the same bytes (its ``.chk``),
    the same at any read size, and gpsd's as gpsd wrote it."""
    import datetime as dt

    from navd.drivers.gpsd import GpsdDecoder

    nmea = path.read_bytes()
    whole = _times(NmeaDecoder(), nmea, len(nmea))
    assert _times(NmeaDecoder(), nmea, size) == whole
    chk = (path.parent / (path.name + ".chk")).read_bytes()
    said = [
        json.loads(ln)["time"]
        for ln in chk.splitlines()
        if b'"class":"TPV"' in ln and b'"time"' in ln
    ]
    got = _times(GpsdDecoder(), chk, size)
    assert got == _times(GpsdDecoder(), chk, len(chk))
    stamps = [g.utc for g in got]  # type: ignore[attr-defined]
    assert stamps == [dt.datetime.fromisoformat(s.replace("Z", "+00:00")) for s in said]
