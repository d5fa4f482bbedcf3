"""Health says what the daemon delivers: every state below was once reported ``ok: true``.

The daemon is driven here without ports or an event loop, on a clock the test
moves, through the same handlers its serial tasks call.
"""

from __future__ import annotations

import asyncio
import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from navd.daemon.daemon import Daemon
from navd.daemon.devices import Ahrs, ModemPinger
from navd.daemon.devices.modem import PING_COUNTS
from navd.daemon.health import RecentTimes
from navd.drivers import ahrs, castle, keller, modem
from navd.drivers.transport import PortHealth
from navd.filter import Navigator
from navd.records import Attitude, Depth, Gps, Pressure, Rpm
from navd.schema import Estimate
from navd.settings import config_from_dict


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Port:
    """A serial port that is open (the pty tests cover the real one)."""

    def __init__(self) -> None:
        self.health = PortHealth(connected=True)
        self.written: list[bytes] = []
        self.on_open = None

    def write(self, data: bytes) -> bool:
        self.written.append(data)
        return True


def _daemon(tmp_path: Path) -> tuple[Daemon, Clock]:
    clock = Clock()
    cfg = config_from_dict({"log": {"dir": str(tmp_path / "log")}})
    d = Daemon(cfg, clock=clock)
    assert set(d.devices) == {"ahrs", "pressure", "motor", "modem", "gps"}
    for dev in d.devices.values():
        dev.transport = Port()  # type: ignore[assignment]
    return d, clock


def _navigate(d: Daemon, clock: Clock, seconds: float, depth_bar: float | None = 1.01325) -> None:
    """Every input arriving as it should, estimates going out at 10 Hz."""
    end = clock.t + seconds
    while clock.t < end:
        clock.t = round(clock.t + 0.1, 6)
        d.feed(Attitude(clock.t, 0.0, 0.0, 0.0))
        d.feed(Rpm(clock.t, 0.0))
        if depth_bar is not None:
            d.feed(Pressure(clock.t, depth_bar))
        if not d.nav.filter.initialised:
            d.feed(Gps(clock.t, 37.05, -80.66, 0.0, 1))
        d._outputs(d.nav.advance(clock.t))


def test_a_navigating_daemon_is_ok(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 10.0)
    h = d.health()
    assert h.degraded == [], h.degraded
    assert h.ok and h.estimates_per_s == pytest.approx(10.0, abs=0.5)


def test_a_stalled_pressure_sensor_is_not_ok(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 10.0)
    _navigate(d, clock, 12.0, depth_bar=None)  # depth frozen for 12 s
    h = d.health()
    assert not h.ok and any(p.startswith("depth: stale") for p in h.degraded)
    assert h.input_age_s["depth"] == pytest.approx(12.0, abs=0.2)


def test_keller_exception_answers_are_not_readings(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 10.0)
    handle = d.devices["pressure"].handle
    records = d.devices["pressure"].records
    dec = d.devices["pressure"].decoder
    dec.request(keller.CH_PRESSURE)
    for rec in dec.feed(_keller_exception(1, 3), clock.t):
        handle(rec)
    h = d.health()
    assert d.devices["pressure"].records == records
    assert not h.ok and any("device error" in p for p in h.degraded)
    # code 32, not initialised (a power blip): initialise again, keep polling
    dec.request(keller.CH_PRESSURE)
    for rec in dec.feed(_keller_exception(1, keller.E_NOT_INITIALISED), clock.t):
        handle(rec)
    assert d.devices["pressure"].transport.written == [keller.encode_init(1)]  # type: ignore[union-attr]


def _keller_exception(addr: int, code: int) -> bytes:
    body = bytes([addr, keller.F_READ_FLOAT | 0x80, code])
    return body + keller.crc16(body).to_bytes(2, "big")


def test_a_modem_that_never_replies_is_not_ok(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)
    pinger = d.devices["modem"]
    assert isinstance(pinger, ModemPinger)
    for _ in range(3):
        pinger.ping_t = clock.t
        _navigate(d, clock, 5.0)
        pinger.handle(modem.ModemReply(clock.t, "no_reply"))
    h = d.health()
    assert not h.ok and any("pings had no range" in p for p in h.degraded)
    assert h.pings["last"] == ["no_reply"] * 3


def test_no_estimates_is_not_ok_and_starves_the_watchdog(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)
    assert d.vitals.navigating(clock.t, d.nav.filter.initialised)
    clock.t += 18.0  # the loop runs, the ports are open, but no estimate went out
    h = d.health()
    assert not h.ok and any(p.startswith("estimates at 0.0/s") for p in h.degraded)
    assert not d.vitals.navigating(clock.t, d.nav.filter.initialised)


def test_a_navigator_that_raises_is_caught_counted_and_restarted(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)

    def boom(rec: object) -> list:
        raise ZeroDivisionError("a bug")

    real = d.nav.feed
    d.nav.feed = boom  # type: ignore[method-assign]
    d.feed(Rpm(clock.t, 0.0))
    d.feed(Rpm(clock.t, 0.0))
    d.nav.feed = real  # type: ignore[method-assign]
    assert d.internal_errors == {"navigator: ZeroDivisionError": 2}
    assert any("internal errors" in p for p in d.health().degraded)
    _navigate(d, clock, 2.0)  # navigation resumes at the next fix
    assert d.nav.filter.initialised


def test_a_vehicle_that_surfaces_with_a_stalled_depth_sensor_takes_gps() -> None:
    nav = Navigator(config_from_dict({}))
    nav.feed(Gps(0.0, None, None, None, 0))  # the receiver acquiring as navd starts
    for k in range(1, 20):
        nav.feed(Gps(k * 0.1, 37.05, -80.66, 0.0, 1))
    nav.feed(Depth(2.5, 4.0))  # dives, then the pressure sensor stalls
    nav.feed(Gps(3.0, 37.05, -80.66, 0.0, 1))
    assert nav.counters["gps_while_submerged"] == 1
    out = []
    for k in range(20):  # surfaced: fixes again, depth still says 4 m
        out += nav.feed(Gps(10.0 + k * 0.1, 37.0501, -80.66, 0.0, 1))
    out += nav.advance(12.0)
    assert nav.counters["gps_with_stale_depth"] == 20
    assert isinstance(out[-1], Estimate) and out[-1].mode != "submerged"
    # the fixes (11 m north, at the warm-up weight) pulled the estimate most of the way
    assert out[-1].lat > 37.05006


def test_bursts_of_corrupt_data_and_a_flood_are_said(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 10.0)
    assert d.health().ok
    d.devices["pressure"].decoder.stats.bad_checksum += 4  # a garbage burst
    for _ in range(1000):  # and the AHRS babbling at ten times its rate (20 Hz asked)
        d.devices["ahrs"].recent.append(clock.t)
    h = d.health()
    assert any(p.startswith("pressure: 4 corrupt frames") for p in h.degraded)
    assert any(p.startswith("ahrs: ") and "records/s" in p for p in h.degraded)
    _navigate(d, clock, 6.0)  # the burst is over, the flood too
    assert not [p for p in d.health().degraded if "corrupt" in p or "records/s" in p]


def test_an_ahrs_that_does_not_answer_the_firmware_probe_is_not_ok(tmp_path: Path) -> None:
    """A 2.x firmware GX3 speaks MIP and says nothing to the single-byte probe."""
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)
    st = d.devices["ahrs"]
    assert isinstance(st, Ahrs)
    st.t_probe = clock.t
    _navigate(d, clock, 4.0)
    h = d.health()
    assert not h.ok and any("firmware probe" in p for p in h.degraded)
    st.handle(ahrs.Firmware(clock.t, 1134))
    h = d.health()
    assert h.devices["ahrs"].info["firmware"] == 1134
    assert not any("firmware probe" in p for p in h.degraded)


def test_the_esc_battery_is_in_health_and_its_error_answer_is_not_a_speed(
    tmp_path: Path,
) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)
    dec = castle.CastleDecoder()
    handle = d.devices["motor"].handle
    for register, answer in ((castle.REG_VOLTAGE, "0f f4 fd"), (castle.REG_SPEED, "ff ff 02")):
        dec.request(register)
        for rec in dec.feed(bytes.fromhex(answer), clock.t):
            handle(rec)
    h = d.health()
    assert h.esc["battery_v"] == pytest.approx(40.0)
    assert h.devices["motor"].device_errors == 1
    assert any("motor: device error" in p for p in h.degraded)


def test_modem_refusals_are_counted(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 5.0)
    pinger = d.devices["modem"]
    assert isinstance(pinger, ModemPinger)
    pinger.ping_t = clock.t
    for rec in modem.ModemDecoder().feed(b"Command 'ATRX2' not found\r\n", clock.t):
        pinger.handle(rec)
    h = d.health()
    assert h.pings["refused"] == 1 and h.pings["last"] == ["refused"]
    assert pinger.ping_t is None  # the ping is over: the next one may go


def test_a_modem_stuck_outside_command_mode_is_not_ok(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    pinger = d.devices["modem"]
    assert isinstance(pinger, ModemPinger)
    pinger.session.opened(clock.t)  # the port opened; the modem never answers the escape
    _navigate(d, clock, 12.0)
    h = d.health()
    assert not h.ok and any("not in command mode" in p for p in h.degraded)
    assert h.modem["ready"] is False


def test_a_silent_ahrs_on_an_open_port_is_soft_reset_and_set_up_again(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    unit = d.devices["ahrs"]
    port = unit.transport
    opened: list[float] = []
    unit.on_open = lambda tr: opened.append(clock.t)  # type: ignore[method-assign]
    port.health.last_rx = clock.t  # type: ignore[union-attr]
    unit.info.update(firmware=1134, hard_iron=[0.0, 0.0, 0.0])  # it said who it is

    async def main() -> None:
        unit.every_second(clock.t)
        assert port.written == []  # type: ignore[union-attr]
        clock.t += 11.0  # nothing from the AHRS since
        unit.every_second(clock.t)
        assert port.written == [ahrs.encode_soft_reset()]  # type: ignore[union-attr]
        await asyncio.sleep(1.1)
        assert opened  # the open sequence again
        unit.every_second(clock.t)  # not again at once
        assert len(port.written) == 1  # type: ignore[union-attr]

    asyncio.run(main())
    assert d.health().devices["ahrs"].resets == 1


def test_an_unanswered_firmware_probe_is_asked_again(tmp_path: Path) -> None:
    """A unit stalled when it was opened answers once it streams again: the probe is
    repeated until it does, and health is ok again then."""
    d, clock = _daemon(tmp_path)
    st = d.devices["ahrs"]
    assert isinstance(st, Ahrs)
    port = st.transport
    st.t_probe = st.t_probe_sent = clock.t
    _navigate(d, clock, 4.0)
    port.health.last_rx = clock.t  # type: ignore[union-attr]
    st.every_second(clock.t)
    assert ahrs.encode_firmware_probe() in port.written  # type: ignore[union-attr]
    st.handle(ahrs.Firmware(clock.t, 1134))
    assert not any("firmware probe" in p for p in d.health().degraded)


def test_each_device_says_its_own_part_and_an_absent_one_idles(tmp_path: Path) -> None:
    d, clock = _daemon(tmp_path)
    _navigate(d, clock, 1.0)
    d.devices["pressure"].temperature_c = 11.5  # type: ignore[attr-defined]
    h = d.health()
    assert h.temperature_c == 11.5 and h.gps_utc is None and h.esc == {}
    assert h.pings["sent"] == 0 and h.pings["fused"] == d.fused
    cfg = config_from_dict(
        {"log": {"dir": str(tmp_path / "log2")}, "devices": {"modem": {"enabled": False},
                                                             "pressure": {"enabled": False}}}
    )  # fmt: skip
    bare = Daemon(cfg, clock=clock)
    assert "modem" not in bare.devices
    h = bare.health()
    assert h.pings == {**dict.fromkeys(PING_COUNTS, 0), "last": []}
    assert h.modem == {"mode": "unknown", "ready": False, "escapes": 0}
    assert h.temperature_c is None


@given(st.lists(st.floats(-1.0, 1.0) | st.just(math.nan), max_size=60), st.integers(1, 20))
def test_recent_tick_times_give_the_quantiles_of_the_last_n(xs: list[float], n: int) -> None:
    """Health's tick lateness and publish latency: the quantiles of the last ``n`` times,
    as sorting them would give (a NaN is not a time, and is left out)."""
    recent = RecentTimes(n)
    for x in xs:
        recent.append(x)
    last = sorted([x for x in xs if not math.isnan(x)][-n:])
    assert len(recent) == len(last)
    for q in (0.0, 0.5, 0.99):
        want = last[min(len(last) - 1, int(q * len(last)))] if last else None
        assert recent.quantile(q) == want
    assert recent.max() == (last[-1] if last else None)
