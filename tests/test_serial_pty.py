"""Every driver against its emulator over a real pseudo-terminal with pyserial."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from navd.drivers import ahrs, castle, gps, keller, modem
from navd.drivers.transport import READ_WINDOW_S, SerialTransport
from navd.hil.emulators.ahrs import AhrsEmulator
from navd.hil.emulators.castle import CastleEmulator
from navd.hil.emulators.gps import GpsEmulator
from navd.hil.emulators.keller import KellerEmulator
from navd.hil.emulators.modem import ModemEmulator
from navd.records import Gps, Pressure, Rpm


async def _until(cond, timeout: float = 5.0) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not cond():
        if loop.time() > end:
            raise AssertionError("condition not met in time")
        await asyncio.sleep(0.02)


def _ahrs_configure(rate_hz: float):
    def on_open(tr: SerialTransport) -> None:
        tr.write(ahrs.encode_stop())
        tr.write(ahrs.encode_sampling(rate_hz))
        tr.write(ahrs.encode_continuous())

    return on_open


def test_ahrs_configured_streams_at_rate_and_survives_a_vanishing_port(tmp_path: Path) -> None:
    async def main() -> None:
        emu = AhrsEmulator(tmp_path / "ahrs")
        emu.yaw_deg = 123.0
        got: list[ahrs.Euler] = []
        tr = SerialTransport(
            str(emu.path),
            115200,
            ahrs.AhrsDecoder(),
            lambda r: got.append(r) if isinstance(r, ahrs.Euler) else None,
            on_open=_ahrs_configure(50.0),
        )
        tr.start()
        await _until(lambda: len(got) > 5)
        assert emu.rate_hz == pytest.approx(50.0)
        n0, t0 = len(got), asyncio.get_running_loop().time()
        await asyncio.sleep(2.0)
        rate = (len(got) - n0) / (asyncio.get_running_loop().time() - t0)
        assert rate == pytest.approx(50.0, rel=0.15)
        assert got[-1].attitude.yaw_deg == pytest.approx(123.0, abs=1e-3)

        emu.port.reconnect()  # unplugged and plugged back: a new pty behind the same path
        await _until(lambda: tr.health.reconnects >= 1 and tr.health.connected)
        n1 = len(got)
        await _until(lambda: len(got) > n1 + 10)  # reconfigured and streaming again
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_ahrs_through_garbage_and_checksum_errors(tmp_path: Path) -> None:
    async def main() -> None:
        emu = AhrsEmulator(tmp_path / "ahrs", seed=3)
        emu.faults.garbage = 0.2
        emu.faults.bad_checksum = 0.2
        dec = ahrs.AhrsDecoder()
        got: list = []
        tr = SerialTransport(str(emu.path), 115200, dec, got.append, on_open=_ahrs_configure(100))
        tr.start()
        await _until(lambda: len(got) > 100)
        assert dec.stats.bad_checksum > 0 and dec.stats.skipped_bytes > 0
        euler = [r for r in got if isinstance(r, ahrs.Euler)]
        assert len(euler) > 90
        assert all(r.attitude.yaw_deg == pytest.approx(0.0, abs=1e-3) for r in euler)
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_keller_initialised_and_polled(tmp_path: Path) -> None:
    async def main() -> None:
        emu = KellerEmulator(tmp_path / "keller", addr=1)
        emu.pressure_bar = 1.25
        dec = keller.KellerDecoder(addr=1)
        got: list = []
        tr = SerialTransport(
            str(emu.path), 9600, dec, got.append, on_open=lambda t: t.write(dec.request_init())
        )
        tr.start()
        await _until(lambda: any(isinstance(r, keller.DeviceInfo) for r in got))
        for _ in range(5):
            tr.write(dec.request(keller.CH_PRESSURE))
            tr.write(dec.request(keller.CH_TEMPERATURE))
            await asyncio.sleep(0.05)
        await _until(lambda: sum(isinstance(r, Pressure) for r in got) == 5)
        assert all(r.bar == pytest.approx(1.25) for r in got if isinstance(r, Pressure))
        assert sum(isinstance(r, keller.Temperature) for r in got) == 5
        await tr.stop()
        emu.close()

    asyncio.run(main())


@pytest.mark.parametrize("end", [b"\r\n", b"\n", b"\r"])
def test_gps_fix_and_no_fix(tmp_path: Path, end: bytes) -> None:
    """A receiver as real ones talk (a second talker, GSV, a vendor's sentence, any line
    end): one fix per epoch, nothing lost to the chatter."""

    async def main() -> None:
        emu = GpsEmulator(tmp_path / "gps", rate_hz=10.0, line_end=end)
        emu.start()
        got: list = []
        tr = SerialTransport(str(emu.path), 9600, gps.NmeaDecoder(), got.append)
        tr.start()
        await _until(lambda: any(isinstance(r, Gps) for r in got))
        assert all(r.fix == 0 for r in got if isinstance(r, Gps))
        emu.lat, emu.lon, emu.alt_msl, emu.geoid_sep = -42.93, 147.36, 0.5, 2.0
        await _until(lambda: any(isinstance(r, Gps) and r.fix for r in got))
        fix = next(r for r in got if isinstance(r, Gps) and r.fix)
        assert fix.lat == pytest.approx(-42.93, abs=1e-6)
        assert fix.lon == pytest.approx(147.36, abs=1e-6)
        assert fix.alt == pytest.approx(2.5)
        await _until(lambda: sum(isinstance(r, Gps) and r.fix for r in got) >= 5)
        fixes = [r for r in got if isinstance(r, Gps) and r.fix]
        # one fix per epoch: the GL talker's GGA for the same epoch is not a second fix
        assert tr.decoder.stats.reasons["duplicate_epoch"] >= len(fixes) - 1
        assert tr.decoder.stats.reasons["proprietary_PGLOR"] >= 5
        assert tr.decoder.stats.bad_frame == 0 and tr.decoder.stats.bad_checksum == 0
        assert not tr.health.internal_errors
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_castle_rpm(tmp_path: Path) -> None:
    async def main() -> None:
        emu = CastleEmulator(tmp_path / "esc", pole_pairs=7)
        emu.rpm = 1150.0
        dec = castle.CastleDecoder(pole_pairs=7)
        got: list = []
        tr = SerialTransport(str(emu.path), 9600, dec, got.append)
        tr.start()
        await _until(lambda: tr.health.connected)
        # one request open at a time, as the protocol has it: the next goes out when the
        # answer is in, so a loaded machine's slow pty cannot turn an answer unsolicited
        for i in range(3):
            tr.write(dec.request_rpm())
            await _until(lambda n=i + 1: len(got) == n)
        assert all(isinstance(r, Rpm) and r.rpm == pytest.approx(1150.0, abs=2.0) for r in got)
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_modem_ranges_after_the_round_trip_and_reports_silence(tmp_path: Path) -> None:
    answer: dict = {"v": (0.3, 222.2, 37.05, -80.66, 3.0)}

    async def main() -> None:
        emu = ModemEmulator(tmp_path / "modem", lambda t: answer["v"], timeout_s=0.3, online=False)
        got: list = []
        tr = SerialTransport(str(emu.path), 9600, modem.ModemDecoder(), got.append)
        tr.start()
        await _until(lambda: tr.health.connected)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        tr.write(modem.encode_range(2))
        await _until(lambda: any(isinstance(r, modem.ModemRange) for r in got))
        assert loop.time() - t0 >= 0.3  # the answer comes after the round trip
        rng = next(r for r in got if isinstance(r, modem.ModemRange))
        assert (rng.range_m, rng.remote, rng.lat, rng.lon, rng.depth) == (
            222.2,
            2,
            37.05,
            -80.66,
            3.0,
        )
        await _until(lambda: not emu.busy)
        answer["v"] = None  # the deck box does not answer
        tr.write(modem.encode_range(2))
        await _until(
            lambda: any(isinstance(r, modem.ModemReply) and r.status == "no_reply" for r in got)
        )
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_modem_emulator_hears_the_world_channel(tmp_path: Path) -> None:
    """The deck box answers with the simulated boat's position after the true round trip."""
    from conftest import mission

    from navd.hil.link import modem_range_fn
    from navd.hil.world import simulate

    m = simulate(mission("claytor-2", 5).scenario, 5)  # a private copy: its channel is used
    ch = m.channel
    ch.p_gb, ch.bad = 0.0, False  # no drops for this test
    asked: list[float] = []

    async def main() -> None:
        loop = asyncio.get_running_loop()
        t0 = loop.time() - 100.0  # mission time 100 s is now
        fn = modem_range_fn(m, t0)
        emu = ModemEmulator(tmp_path / "modem", lambda t: (asked.append(t), fn(t))[1], online=False)
        got: list = []
        tr = SerialTransport(str(emu.path), 9600, modem.ModemDecoder(), got.append)
        tr.start()
        await _until(lambda: tr.health.connected)
        state = ch.rng.bit_generator.state
        sent = loop.time()
        tr.write(modem.encode_range(2))
        await _until(lambda: any(isinstance(r, modem.ModemReply) for r in got))
        (r,) = [x for x in got if isinstance(x, modem.ModemRange)]
        ch.rng.bit_generator.state = state  # replay the same draw offline
        ch.bad = False
        want = ch.ping(asked[0] - t0)
        assert r.range_m == pytest.approx(want.m, abs=0.051)
        if want.beacon_lat is not None:
            assert r.lat == pytest.approx(want.beacon_lat, abs=1e-7)
        assert r.t - sent >= want.t - want.t_ping - 0.01  # not before the true round trip
        await tr.stop()
        emu.close()

    asyncio.run(main())


def test_a_quiet_port_stays_open_and_a_paced_line_is_read_in_few_wake_ups(
    tmp_path: Path,
) -> None:
    """Ports are read once a read window (50 ms), not at every byte: an idle tty (whose
    empty reads look like a hang-up's) is kept, and a 4800-baud GPS, whose bytes arrive
    two at a time, is read at most once a window with every sentence intact."""

    async def main() -> None:
        quiet = GpsEmulator(tmp_path / "quiet")  # never started: says nothing
        talker = GpsEmulator(tmp_path / "gps", rate_hz=2.0, baudrate=4800)
        talker.start()
        got: list = []
        idle = SerialTransport(str(quiet.path), 4800, gps.NmeaDecoder(), got.append)
        tr = SerialTransport(str(talker.path), 4800, gps.NmeaDecoder(), got.append)
        reads = 0
        feed = tr.decoder.feed

        def counting(data: bytes, t: float) -> list:
            nonlocal reads
            reads += 1
            return feed(data, t)

        tr.decoder.feed = counting  # type: ignore[method-assign]
        idle.start()
        tr.start()
        await _until(lambda: tr.health.connected and idle.health.connected)
        await asyncio.sleep(3.0)
        assert idle.health.opens == 1 and idle.health.reconnects == 0
        assert tr.health.reconnects == 0
        assert sum(isinstance(r, Gps) for r in got) >= 2
        assert reads <= 3.0 / READ_WINDOW_S + 2
        await tr.stop()
        await idle.stop()
        quiet.close()
        talker.close()

    asyncio.run(main())


def test_a_port_whose_read_raises_does_not_stop_the_others(tmp_path: Path) -> None:
    """The ports are read together: a bug in one port's read is logged, and the next
    window reads every port again."""

    async def main() -> None:
        bad_emu = GpsEmulator(tmp_path / "bad", rate_hz=5.0)
        good_emu = GpsEmulator(tmp_path / "good", rate_hz=5.0)
        bad_emu.start()
        good_emu.start()
        got: list = []
        bad = SerialTransport(str(bad_emu.path), 9600, gps.NmeaDecoder(), lambda r: None)

        def boom() -> None:
            raise RuntimeError("a bug")

        bad._read = boom  # type: ignore[method-assign]
        good = SerialTransport(str(good_emu.path), 9600, gps.NmeaDecoder(), got.append)
        bad.start()
        good.start()
        await _until(lambda: sum(isinstance(r, Gps) for r in got) >= 5)
        await bad.stop()
        await good.stop()
        bad_emu.close()
        good_emu.close()

    asyncio.run(main())
