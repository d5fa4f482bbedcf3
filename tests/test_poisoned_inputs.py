"""Inputs that once stopped navigation or lost data: late ranges, poisoned numbers, bad logs.

Each test here failed before its fix (the reliability issue's findings 1, 2, 3 and 6).
"""

from __future__ import annotations

import asyncio
import io
import math
import time
from pathlib import Path

import pytest
from serialised import rows

from navd.drivers import gps, keller, modem
from navd.drivers.transport import SerialTransport
from navd.filter import Navigator
from navd.formats.mlog import MAX_LINE_CHARS, LogError, Skipped, iter_lines, read_measurement_log
from navd.hil.emulators.modem import ModemEmulator
from navd.records import Attitude, Gps, Pressure, Range, Rpm
from navd.settings import config_from_dict

LAT0, LON0 = 37.05, -80.66
BEACON = (37.0510, -80.6600, 2.0)  # about 110 m north of the start


def _nmea(body: str) -> bytes:
    cs = 0
    for ch in body.encode():
        cs ^= ch
    return f"${body}*{cs:02X}\r\n".encode()


def _dive(range_delay_s: float) -> tuple[Navigator, list[dict]]:
    """GPS, then a submerged run at 1 m/s north with a ping every 10 s.

    Each range reaches the navigator ``range_delay_s`` after its own time stamp, with
    AHRS and RPM records of the meantime ahead of it, as a 9600-baud modem delivers it.
    """
    nav = Navigator(config_from_dict({"navigation": {"speed": {"rpm_per_mps": 1000.0}}}))
    out: list[dict] = []
    for k in range(50):
        out += nav.feed(Gps(k * 0.1, LAT0, LON0, 0.0, 1))
        out += nav.feed(Attitude(k * 0.1 + 0.01, 0.0, 0.0, 0.0))
    pending: list[tuple[float, Range]] = []
    t = 5.0
    while t < 65.0:
        t = round(t + 0.01, 2)
        k = round(t * 100)
        if k % 5 == 0:
            out += nav.feed(Attitude(t, 0.0, 0.0, 0.0))
            out += nav.feed(Rpm(t, 1000.0))
        if k % 1000 == 0:
            # a reply every 10 s, 0.2 s after its ping, its last byte 30 ms before a tick:
            # its location line, 55 ms long, ends after the filter has stepped past it
            r = round(t - 0.03, 2)
            pending.append((r + range_delay_s, Range(r, r - 0.2, 80.0, "udb", *BEACON)))
        if k % 10 == 0:
            out += nav.advance(t)  # the daemon's 10 Hz tick
            # depth below the surface: the vehicle is submerged
            from navd.records import Depth

            out += nav.feed(Depth(t, 2.0))
        while pending and pending[0][0] <= t:
            out += nav.feed(pending.pop(0)[1])
    return nav, out


def test_a_range_completed_after_other_records_is_still_fused() -> None:
    """Finding 1: at 9600 baud the location line arrives 55 ms after the Range line."""
    on_time, out_a = _dive(0.0)
    late, out_b = _dive(0.055)
    ranges_a = [o for o in rows(out_a) if o["type"] == "range"]
    ranges_b = [o for o in rows(out_b) if o["type"] == "range"]
    assert len(ranges_b) == len(ranges_a) == 6
    assert late.counters["skipped_out_of_order"] == 0
    assert late.counters["ranges_late"] == 6
    for a, b in zip(ranges_a, ranges_b, strict=True):
        assert a["t"] == b["t"] and a["accepted"] == b["accepted"]
        # the same geometry: fused at its own time, not at its arrival
        assert b["residual_m"] == pytest.approx(a["residual_m"], abs=0.05)
    est_a = [o for o in rows(out_a) if o["type"] == "estimate"][-1]
    est_b = [o for o in rows(out_b) if o["type"] == "estimate"][-1]
    assert math.dist((est_a["lat"], est_a["lon"]), (est_b["lat"], est_b["lon"])) < 1e-6


def test_a_range_later_than_any_line_could_make_it_is_out_of_order() -> None:
    nav, out = _dive(3.0)
    assert not [o for o in rows(out) if o["type"] == "range"]
    assert nav.counters["skipped_out_of_order"] == 6


def test_emulated_modem_paces_its_lines_at_the_baud_rate(tmp_path: Path) -> None:
    """The bench shows real timing: the location line lands after the Range line."""

    async def main() -> None:
        emu = ModemEmulator(
            tmp_path / "modem",
            lambda t: (0.05, 75.0, *BEACON),
            timeout_s=0.3,
            baudrate=9600,
            online=False,
        )
        got: list[tuple[float, object]] = []
        # read every millisecond: what is timed here is the emulator's line, not the
        # daemon's 50 ms read window (navd/drivers/transport.py)
        tr = SerialTransport(
            str(emu.path),
            9600,
            modem.ModemDecoder(),
            lambda r: got.append((time.monotonic(), r)),
            read_window_s=0.001,
        )
        tr.start()
        while not tr.health.connected:
            await asyncio.sleep(0.01)
        tr.write(modem.encode_range(2))
        t_end = time.monotonic() + 3.0
        while not any(isinstance(r, modem.ModemReply) for _, r in got):
            assert time.monotonic() < t_end
            await asyncio.sleep(0.01)
        await tr.stop()
        emu.close()
        ((t_done, rng),) = [(t, r) for t, r in got if isinstance(r, modem.ModemRange)]
        assert rng.lat == BEACON[0]
        # about 53 bytes of location line between the Range line and the complete range
        assert t_done - rng.t >= 0.04

    asyncio.run(main())


@pytest.mark.parametrize("alt", ["nan", "1e20", "-inf"])
def test_gga_with_an_impossible_altitude_is_refused(alt: str) -> None:
    """Finding 2: one GGA with altitude nan used to stop navigation for good."""
    dec = gps.NmeaDecoder()
    recs = dec.feed(_nmea(f"GPGGA,120000,3703.000,N,08039.600,W,1,08,0.9,{alt},M,0.0,M,,"), 0.0)
    assert recs == []
    assert dec.stats.bad_frame == 1 and dec.stats.records == 0


def test_gga_with_an_impossible_hdop_is_refused() -> None:
    dec = gps.NmeaDecoder()
    assert dec.feed(_nmea("GPGGA,120000,3703.000,N,08039.600,W,1,08,nan,10.0,M,0.0,M,,"), 0.0) == []


@pytest.mark.parametrize("dirs", [(",", ",W"), ("N", ""), ("X", "W"), ("N", "Q")])
def test_gga_without_hemispheres_is_not_a_fix_at_zero(dirs: tuple[str, str]) -> None:
    """Finding 3: pynmea2 reads a missing hemisphere as 0.0 north or east."""
    ns, ew = dirs
    ns = ns.rstrip(",")
    ew = ew.lstrip(",")
    dec = gps.NmeaDecoder()
    body = f"GPGGA,120000,3703.000,{ns},08039.600,{ew},1,08,0.9,10.0,M,0.0,M,,"
    recs = dec.feed(_nmea(body), 0.0)
    assert not [r for r in recs if isinstance(r, Gps) and r.fix]
    assert dec.stats.bad_frame == 1


@pytest.mark.parametrize("quality", [6, 7, 8])
def test_gga_estimated_manual_or_simulated_is_not_a_fix(quality: int) -> None:
    dec = gps.NmeaDecoder()
    body = f"GPGGA,120000,3703.000,N,08039.600,W,{quality},08,0.9,10.0,M,0.0,M,,"
    (rec,) = dec.feed(_nmea(body), 0.0)
    assert isinstance(rec, Gps) and rec.fix == 0 and rec.lat is None


def test_a_nan_altitude_that_reaches_the_navigator_does_not_poison_it() -> None:
    nav = Navigator(config_from_dict({}))
    out: list[dict] = []
    for k in range(20):
        out += nav.feed(Gps(k * 0.1, LAT0, LON0, 0.0 if k != 5 else math.nan, 1))
    out += nav.advance(2.5)
    est = [o for o in rows(out) if o["type"] == "estimate"]
    assert est and math.isfinite(est[-1]["lat"]) and nav.surface_altitude == 0.0
    assert nav.counters["skipped_implausible"] == 1


@pytest.mark.parametrize("bar", [-5.0, 999999.0, math.nan])
def test_keller_pressure_beyond_the_log_readers_bounds_is_refused(bar: float) -> None:
    """Live and replay agree: the decoder refuses what the log reader would."""
    import struct

    dec = keller.KellerDecoder(1)
    dec.request(keller.CH_PRESSURE)
    body = bytes([1, keller.F_READ_FLOAT]) + struct.pack(">f", bar) + b"\x00"
    frame = body + keller.crc16(body).to_bytes(2, "big")
    assert [r for r in dec.feed(frame, 0.0) if isinstance(r, Pressure)] == []
    assert dec.stats.bad_frame == 1


def test_a_huge_rpm_in_a_log_is_refused_not_walked() -> None:
    """Finding 6: rpm 1e300 made one geodesic step take practically forever."""
    nav = Navigator(config_from_dict({}))
    for k in range(10):
        nav.feed(Gps(k * 0.1, LAT0, LON0, 0.0, 1))
    t0 = time.perf_counter()
    nav.feed(Rpm(1.05, 1e300))
    out = nav.advance(3.0)
    assert time.perf_counter() - t0 < 5.0
    assert nav.counters["skipped_implausible"] == 1
    assert all(math.isfinite(o["lat"]) for o in rows(out))


def _lines(*recs: str) -> list[str]:
    return [r + "\n" for r in recs]


def test_one_record_far_in_the_future_is_skipped_not_made_the_clock() -> None:
    lines = _lines(
        '{"type":"rpm","t":1.0,"rpm":100}',
        '{"type":"rpm","t":501.0,"rpm":100}',
        '{"type":"rpm","t":1.1,"rpm":100}',
        '{"type":"rpm","t":1.2,"rpm":100}',
    )
    items = [item for _, item in iter_lines(lines)]
    assert [getattr(i, "t", None) for i in items if not isinstance(i, Skipped)] == [1.0, 1.1, 1.2]
    (skip,) = [i for i in items if isinstance(i, Skipped)]
    assert skip.line == 3 and "far out of line" in skip.reason


def test_a_real_gap_in_a_log_is_kept() -> None:
    lines = _lines(
        '{"type":"rpm","t":1.0,"rpm":100}',
        '{"type":"rpm","t":501.0,"rpm":100}',
        '{"type":"rpm","t":501.1,"rpm":100}',
    )
    assert [i.t for _, i in iter_lines(lines)] == [1.0, 501.0, 501.1]  # type: ignore[union-attr]


def test_a_late_range_reads_back_but_other_records_may_not_go_back() -> None:
    lines = _lines(
        '{"type":"rpm","t":10.0,"rpm":100}',
        '{"type":"range","t":9.95,"t_ping":9.5,"m":50,"beacon":"udb"}',
        '{"type":"rpm","t":9.9,"rpm":100}',
    )
    items = [i for _, i in iter_lines(lines)]
    assert isinstance(items[1], Range)
    assert isinstance(items[2], Skipped) and "back in time" in items[2].reason


def test_a_giant_line_is_skipped_in_bounded_memory(tmp_path: Path) -> None:
    import tracemalloc

    p = tmp_path / "big.jsonl"
    with p.open("w") as fh:
        fh.write(
            '{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T00:00:00Z"}\n'
        )
        fh.write('{"type":"rpm","t":1.0,"rpm":100}\n')
        fh.write('{"type":"rpm","t":1.5,"junk":"' + "x" * 20_000_000 + '"}\n')
        fh.write('{"type":"rpm","t":2.0,"rpm":100}\n')
    tracemalloc.start()
    log = read_measurement_log(p)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert [r.t for r in log.records] == [1.0, 2.0]
    assert len(log.skipped) == 1 and str(MAX_LINE_CHARS) in log.skipped[0].reason
    assert peak < 5_000_000


def test_replay_passes_over_an_empty_file_among_rotated_logs(tmp_path: Path) -> None:
    from navd.analysis.replay import replay

    head = '{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T00:00:00Z"}\n'
    a = tmp_path / "navd-1.jsonl"
    a.write_text(
        head
        + "".join(
            f'{{"type":"gps","t":{k / 10},"lat":37.05,"lon":-80.66,"fix":1}}\n' for k in range(30)
        )
    )
    empty = tmp_path / "navd-2.jsonl"
    empty.write_text("")
    err = io.StringIO()
    res = replay([a, empty], config_from_dict({}), tmp_path / "out.jsonl", err=err)
    assert "empty file, passed over" in err.getvalue()
    assert res.estimates > 0 and '"type":"estimate"' in (tmp_path / "out.jsonl").read_text()
    with pytest.raises(LogError):
        read_measurement_log(empty)


def test_a_daemon_log_replays_its_ticks_where_they_were_taken() -> None:
    """Live, a range completed after a tick is fused after it; replay must do the same.

    The log holds the tick (its ``estimate`` line) before the late range, and replay
    steps the filter there: the estimate at the tick does not see the range.
    """
    from navd.records import Tick

    def replay(lines: list[str]) -> dict[float, dict]:
        nav = Navigator(config_from_dict({"navigation": {"speed": {"rpm_per_mps": 1000.0}}}))
        out: list[dict] = []
        for _, rec in iter_lines(lines):
            assert not isinstance(rec, Skipped)
            out += nav.feed(rec)
        return {o["t"]: o for o in rows(out) if o["type"] == "estimate"}

    head = [f'{{"type":"gps","t":{k / 10},"lat":37.05,"lon":-80.66,"fix":1}}\n' for k in range(50)]
    head += ['{"type":"depth","t":5.01,"m":2.0}\n', '{"type":"rpm","t":5.02,"rpm":1000}\n']
    late = '{"type":"range","t":9.96,"t_ping":9.5,"m":106.0,"beacon":"udb",'
    late += '"beacon_lat":37.051,"beacon_lon":-80.66}\n'
    body = [f'{{"type":"heading","t":{5.05 + 0.1 * k:.2f},"deg":0.0}}\n' for k in range(50)]
    tick = '{"type":"estimate","t":10.0,"lat":0,"lon":0}\n'
    after = ['{"type":"heading","t":10.05,"deg":0.0}\n']
    logged = replay(head + body + [tick, late] + after)  # as the daemon wrote it
    fused = replay(head + body + [late] + after)  # had the range come before the tick
    assert fused[10.0]["std_n"] < logged[10.0]["std_n"]  # (it is accepted: it matters)
    without = replay(head + body + after)  # the range never came
    assert logged[10.0]["std_n"] == without[10.0]["std_n"]  # the tick did not see it
    assert isinstance(next(r for _, r in iter_lines([tick])), Tick)
