"""What the published protocol documents say each device does, as golden vectors.

Each test names its source.  The driver decodes the vector, and the emulator
behaves as the device does, so the emulators cannot share a driver's mistake.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest
from serialised import rows

from navd.drivers import ahrs, castle, gps, keller, modem
from navd.drivers.codec import DeviceError
from navd.filter.gpsfix import fix_std as _gps_std
from navd.hil.emulators.ahrs import AhrsEmulator
from navd.hil.emulators.castle import CastleEmulator
from navd.hil.emulators.keller import KellerEmulator
from navd.hil.emulators.modem import ModemEmulator
from navd.records import Pressure, Rpm
from navd.settings import ConfigError, config_from_dict


def _answers(emu, request: bytes, wait_s: float = 0.05) -> list[bytes]:
    """What an emulator puts on the line for ``request``."""
    sent: list[bytes] = []

    async def main() -> None:
        emu.send = sent.append
        emu.on_bytes(request)
        await asyncio.sleep(wait_s)
        emu.close()

    asyncio.run(main())
    return sent


# -- Castle Serial Link ------------------------------------------------------------------
# Castle Creations, "Castle Serial Link Communication Protocol" v1.5;
# dgatf/castle_telemetry (castle_telemetry.cpp) builds the same frames.


def test_castle_request_is_five_bytes_with_the_device_byte() -> None:
    """Device 0, register 5: ``80 05 00 00 7B``; the five bytes sum to 0 mod 256."""
    assert castle.encode_read(5, device_id=0) == bytes.fromhex("80 05 00 00 7b")
    assert castle.encode_read(5, device_id=3) == bytes.fromhex("83 05 00 00 78")
    assert castle.CastleDecoder(device_id=0).request_rpm() == bytes.fromhex("80 05 00 00 7b")


def test_castle_emulator_answers_the_real_request_only(tmp_path: Path) -> None:
    emu = CastleEmulator(tmp_path / "esc", device_id=0)
    emu.rpm = 1000 / 2042 * 20416.66  # raw 1000
    assert _answers(emu, bytes.fromhex("80 05 00 00 7b")) == [bytes.fromhex("03 e8 15")]
    # the four-byte request navd once sent is not a request: no answer
    emu = CastleEmulator(tmp_path / "esc2", device_id=0)
    assert _answers(emu, bytes.fromhex("05 00 00 fb")) == []
    # another device id: not ours to answer
    emu = CastleEmulator(tmp_path / "esc3", device_id=1)
    assert _answers(emu, bytes.fromhex("80 05 00 00 7b")) == []


def test_castle_five_zero_bytes_clear_a_half_request(tmp_path: Path) -> None:
    """Five ``00`` bytes clear the command buffer: a half request left in it is dropped."""
    emu = CastleEmulator(tmp_path / "esc")
    emu.rpm = 1000 / 2042 * 20416.66
    half = bytes.fromhex("80 05")  # a request cut by a reset
    assert _answers(emu, half + castle.CLEAR + bytes.fromhex("80 05 00 00 7b")) == [
        bytes.fromhex("03 e8 15")
    ]
    assert castle.CastleDecoder().request_clear() == bytes(5)


def test_castle_ffff_is_an_error_answer_not_a_speed() -> None:
    """``FF FF`` is the error answer; with 40 pole pairs it would read 4999 RPM."""
    dec = castle.CastleDecoder(pole_pairs=40)
    dec.request_rpm()
    (rec,) = dec.feed(bytes.fromhex("ff ff 02"), 1.0)
    assert isinstance(rec, DeviceError) and not isinstance(rec, Rpm)
    # the next answer is matched to the next request
    dec.request_rpm()
    (rpm,) = dec.feed(bytes.fromhex("03 e8 15"), 2.0)
    assert rpm.rpm == pytest.approx(1000 / 2042 * 20416.66 / 40)


def test_castle_status_registers() -> None:
    """Register 0 is battery volts (scale 20: raw 4084 is 40.0 V), 2 current (50), 6
    temperature (30)."""
    dec = castle.CastleDecoder()
    assert dec.request(castle.REG_VOLTAGE) == bytes.fromhex("80 00 00 00 80")
    (v,) = dec.feed(bytes.fromhex("0f f4 fd"), 1.0)
    assert v == castle.EscStatus(1.0, "battery_v", pytest.approx(40.0))
    assert castle.value_of(castle.REG_CURRENT, 2042) == pytest.approx(50.0)
    assert castle.value_of(castle.REG_TEMPERATURE, 2042) == pytest.approx(30.0)
    # polled at a low rate in place of the speed: each register every few seconds
    d = castle.CastleDecoder()
    asked = [d.request_poll()[1] for _ in range(30)]
    assert asked.count(castle.REG_SPEED) == 27
    assert {r for r in asked if r != castle.REG_SPEED} == set(castle.STATUS)


def test_castle_emulator_status_and_unknown_register(tmp_path: Path) -> None:
    emu = CastleEmulator(tmp_path / "esc")
    emu.battery_v = 40.0
    assert _answers(emu, castle.encode_read(castle.REG_VOLTAGE)) == [bytes.fromhex("0f f4 fd")]
    emu = CastleEmulator(tmp_path / "esc2")
    assert _answers(emu, castle.encode_read(9)) == [bytes.fromhex("ff ff 02")]


# -- Keller Serie 30 ---------------------------------------------------------------------
# KELLER, "Communication protocol Serie 30" v2.2, section 4.8: the F73 status byte.


def test_keller_p1_measuring_error_is_not_a_depth() -> None:
    """1.5 bar with status bit 1 (P1 measuring error) set."""
    dec = keller.KellerDecoder(250)
    dec.request(keller.CH_PRESSURE)
    (rec,) = dec.feed(bytes.fromhex("fa 49 3f c0 00 00 02 92 e6"), 1.0)
    assert isinstance(rec, DeviceError) and "P1" in rec.what
    # the next reading with status 0 is a pressure again
    dec.request(keller.CH_PRESSURE)
    assert dec.feed(bytes.fromhex("fa 49 3f c0 00 00 00 53 67"), 2.0) == [Pressure(2.0, 1.5)]


def test_keller_tob1_error_is_not_a_temperature() -> None:
    """12.0 degrees C with status bit 4 (TOB1 error) set."""
    dec = keller.KellerDecoder(250)
    dec.request(keller.CH_TEMPERATURE)
    (rec,) = dec.feed(bytes.fromhex("fa 49 41 40 00 00 10 55 67"), 1.0)
    assert isinstance(rec, DeviceError) and "TOB1" in rec.what


def test_keller_crc_high_byte_first_only() -> None:
    """The manual's F48 example ``FA 30 04 43`` sends the CRC high byte first (DUNE's
    Keller task too); no source has the reversed form, so it is a bad frame."""
    dec = keller.KellerDecoder(250)
    dec.request(keller.CH_PRESSURE)
    good = bytes.fromhex("fa 49 3f c0 00 00 00 53 67")
    assert dec.feed(good[:-2] + good[-2:][::-1], 1.0) == []
    assert dec.stats.bad_checksum >= 1


def test_keller_emulator_reports_its_status(tmp_path: Path) -> None:
    emu = KellerEmulator(tmp_path / "k", addr=250)
    emu.pressure_bar, emu.status = 1.5, 0x02
    (frame,) = _answers(emu, keller.encode_read_float(250, keller.CH_PRESSURE))
    assert frame == bytes.fromhex("fa 49 3f c0 00 00 02 92 e6")


# -- NMEA 0183 GGA quality ---------------------------------------------------------------
# NMEA 0183 GGA field 6, as tabulated in receiver manuals (Furuno, Epson): 0 invalid,
# 1 GPS, 2 DGPS, 3 PPS, 4 RTK, 5 float RTK, 6 estimated, 7 manual, 8 simulator.


def _gga(quality: int) -> bytes:
    from navd.hil.emulators.gps import sentence

    return sentence(f"GPGGA,123519,4807.038,N,01131.000,E,{quality},08,0.9,545.4,M,46.9,M,,")


@pytest.mark.parametrize("quality", [6, 7, 8])
def test_gga_estimated_manual_simulated_are_not_fixes(quality: int) -> None:
    (rec,) = gps.NmeaDecoder().feed(_gga(quality), 1.0)
    assert rec.fix == 0 and rec.lat is None and rec.quality == quality


@pytest.mark.parametrize("quality", [3, 4, 5])
def test_gga_pps_and_rtk_are_fixes_and_carry_their_quality(quality: int) -> None:
    (rec,) = gps.NmeaDecoder().feed(_gga(quality), 1.0)
    assert rec.fix in (1, 2) and rec.lat == pytest.approx(48.1173) and rec.quality == quality


def test_the_filter_weights_a_fix_by_quality_and_hdop() -> None:
    assert _gps_std(3.0, 1.0, 1) == 3.0
    assert _gps_std(3.0, 2.0, 1) == 6.0  # the same receiver, worse geometry
    assert _gps_std(3.0, 1.0, 4) < _gps_std(3.0, 1.0, 5) < _gps_std(3.0, 1.0, 1)


# -- Benthos ATM-900 ---------------------------------------------------------------------
# GobySoft/goby3, src/acomms/modemdriver/benthos_atm900_driver_fsm.cpp: the Range line
# alone is the ranging result; the shell refuses with "Command '...' not found"; no
# reply is "Response Not Received." after the modem's own timeout (2 to 99.5 s).

GOBY_RANGE = b"Range 1 to 2 : 1499.6 m  (Round-trip  1999.5 ms) speed  0.0 m/s\r\n"


def test_a_range_does_not_wait_for_the_next_line() -> None:
    dec = modem.ModemDecoder()
    assert dec.feed(b"TX time 12:00:00\r\n" + GOBY_RANGE, 10.0) == []  # its location may follow
    assert dec.expire(10.0 + modem.LOCATION_WAIT_S / 2) == []
    (rng,) = dec.expire(10.0 + modem.LOCATION_WAIT_S)
    # stamped with its own line; the round trip and relative speed read from it
    assert rng == modem.ModemRange(10.0, 1499.6, 2, twtt_s=1.9995, speed_mps=0.0)
    assert dec.stats.skipped_bytes == 0  # the TX time line is the modem's, not garbage


def test_a_location_line_completes_the_range_without_restamping_it() -> None:
    dec = modem.ModemDecoder()
    dec.feed(GOBY_RANGE, 10.0)
    (rng,) = dec.feed(b"Remote Lat: 37.0490112 Lon: -80.6670001 Depth: 3.0\r\n", 10.06)
    assert (rng.t, rng.range_m, rng.lat, rng.lon, rng.depth) == (
        10.0,
        1499.6,
        37.0490112,
        -80.6670001,
        3.0,
    )


@pytest.mark.parametrize("line", [b"ERROR", b"Command 'ATRX2' not found"])
def test_both_refusals_are_refusals(line: bytes) -> None:
    (reply,) = modem.ModemDecoder().feed(line + b"\r\n", 1.0)
    assert reply == modem.ModemReply(1.0, "refused")


def test_no_reply_with_its_full_stop() -> None:
    (reply,) = modem.ModemDecoder().feed(b"Response Not Received.\r\n", 1.0)
    assert reply.status == "no_reply"


def test_modem_emulator_speaks_as_the_atm900(tmp_path: Path) -> None:
    emu = ModemEmulator(tmp_path / "m", lambda t: (1.9995, 1499.6, None, None, None), online=False)
    (text,) = _answers(emu, b"ATRX2\r", wait_s=2.2)
    assert text == GOBY_RANGE + b"OK\r\n"
    emu = ModemEmulator(tmp_path / "m2", lambda t: None, timeout_s=0.1, online=False)
    assert _answers(emu, b"ATRX2\r", wait_s=0.3) == [b"Response Not Received.\r\n"]
    emu = ModemEmulator(tmp_path / "m3", lambda t: None, online=False)
    assert _answers(emu, b"ATFOO\r") == [b"Command 'ATFOO' not found\r\n"]


def test_check_config_wants_navd_to_outlast_the_modem() -> None:
    with pytest.raises(ConfigError, match=r"devices\.modem\.reply_timeout_s"):
        config_from_dict({"devices": {"modem": {"reply_timeout_s": 8, "modem_timeout_s": 10}}})
    with pytest.raises(ConfigError, match=r"devices\.modem\.modem_timeout_s"):
        config_from_dict({"devices": {"modem": {"modem_timeout_s": 1}}})  # the modem's floor: 2 s
    config_from_dict({"devices": {"modem": {"reply_timeout_s": 12, "modem_timeout_s": 10}}})


# -- 3DM-GX3-25 --------------------------------------------------------------------------
# MicroStrain, "3DM-GX3-25 Single Byte Data Communications Protocol" v1.14; LSTS DUNE,
# Sensors/Microstrain3DMGX3 (the 0xE9 firmware probe).


def test_gx3_refusal_is_decoded_and_counted() -> None:
    dec = ahrs.AhrsDecoder()
    (rec,) = dec.feed(bytes.fromhex("21 00 21"), 1.0)
    assert isinstance(rec, DeviceError) and rec.code == 0x21


def test_gx3_emulator_refuses_wrong_confirmation_bytes(tmp_path: Path) -> None:
    emu = AhrsEmulator(tmp_path / "a")
    assert _answers(emu, bytes.fromhex("c4 c1 2a ce")) == [bytes.fromhex("21 00 21")]


def test_gx3_sampling_flags_are_orientation_and_coning_sculling() -> None:
    frame = ahrs.encode_sampling(20.0)
    flags = int.from_bytes(frame[6:8], "big")
    assert flags & 0x01  # bit 0: orientation
    assert flags & 0x02  # bit 1: coning and sculling compensation


def test_gx3_firmware_probe(tmp_path: Path) -> None:
    """0xE9 is answered ``E9 <u32 version> <u16 sum>``: version 1134 is 1.1.34."""
    assert ahrs.encode_firmware_probe() == b"\xe9"
    emu = AhrsEmulator(tmp_path / "a", firmware=1134)
    (frame,) = _answers(emu, b"\xe9")
    assert frame == bytes.fromhex("e9 00 00 04 6e 01 5b")
    (rec,) = ahrs.AhrsDecoder().feed(frame, 1.0)
    assert rec == ahrs.Firmware(1.0, 1134)


def test_a_mip_unit_is_refused_not_streamed_from(tmp_path: Path) -> None:
    """A 2.x firmware unit speaks MIP: its frames (here the MIP ping's ACK, ``75 65 01
    04 04 F1 01 00 D5 6A``) are a device error, and single-byte commands get nothing."""
    (rec,) = ahrs.AhrsDecoder().feed(bytes.fromhex("75 65 01 04 04 f1 01 00 d5 6a"), 1.0)
    assert isinstance(rec, DeviceError) and "MIP" in rec.what
    emu = AhrsEmulator(tmp_path / "a", mip=True)
    assert _answers(emu, b"\xe9" + ahrs.encode_continuous()) == []


def test_castle_one_request_open_at_a_time() -> None:
    """Answers carry no header: after a lost answer, the next answer is the next
    request's, never read as the register asked before (a voltage as a speed)."""
    dec = castle.CastleDecoder()
    dec.request(castle.REG_VOLTAGE)  # never answered
    dec.request_rpm()
    (rec,) = dec.feed(bytes.fromhex("03 e8 15"), 1.0)
    assert isinstance(rec, Rpm) and dec.stats.reasons["unanswered"] == 1


def test_the_filter_ranges_from_the_modems_round_trip() -> None:
    """The round trip does not depend on the modem's sound-speed setting: a modem set to
    1400 m/s prints a range 7 % short, and its round trip still gives the true range."""
    from navd.filter import Navigator
    from navd.records import Attitude, Depth, Gps, Range

    cfg = config_from_dict({"navigation": {"sound_speed": {"model": "fixed", "fixed_mps": 1500.0}}})
    nav = Navigator(cfg)
    nav.feed(Depth(0.0, 0.0))
    nav.feed(Attitude(0.0, 0.0, 0.0, 0.0))
    nav.feed(Gps(0.0, 37.0, -80.0, 0.0, 1))
    true_m = 300.0
    twtt = 2 * true_m / 1500.0
    outs = nav.feed(Range(1.0, 0.8, 1400.0 * twtt / 2, "udb", 37.0, -79.99, 0.0, twtt))
    (d,) = [o for o in rows(outs) if o.get("type") == "range"]
    assert d["range_m"] == pytest.approx(true_m)


# GobySoft/goby3 benthos_atm900_driver_fsm.cpp: to reach command mode, "+++" and CR after
# at least 1 s of silence (Goby waits 1.3 s); in command mode "+++" gets "Command '+++'
# not found" or a "user:N>" prompt; "CONNECT" means the modem went online, a "Lowpower"
# prompt that it sleeps.


@pytest.mark.parametrize(
    "text,mode",
    [
        (b"Command '+++' not found\r\n", "command"),
        (b"\r\nuser:1> ", "command"),  # the prompt waits on its line, with no CR LF
        (b"CONNECT 2400\r\n", "online"),
        (b"user:1 Lowpower> ", "lowpower"),
    ],
)
def test_the_modem_says_its_mode(text: bytes, mode: str) -> None:
    (rec,) = modem.ModemDecoder().feed(text, 1.0)
    assert rec == modem.ModemMode(1.0, mode)


def test_the_session_escapes_after_the_guard_and_checks_with_at() -> None:
    s = modem.ModemSession()
    s.opened(0.0)
    assert s.poll(1.0) == b""  # the guard: silence first
    assert s.poll(modem.GUARD_S) == b"+++\r"
    s.seen(modem.ModemMode(1.5, "command"))
    assert s.poll(1.6) == b"AT\r" and not s.ready
    s.seen(modem.ModemReply(1.7, "ok"))
    assert s.ready and s.mode == "command"
    # the modem falls back online: escape again (the host has been silent long enough)
    s.seen(modem.ModemMode(50.0, "online"))
    assert not s.ready and s.poll(50.1) == b"+++\r" and s.escapes == 2
    s.seen(modem.ModemMode(50.2, "command"))
    assert s.poll(50.3) == b"AT\r"
    s.seen(modem.ModemReply(50.4, "ok"))
    # a ping the modem never answered at all: it is not listening, escape again
    s.wrote(60.0)
    s.lost(68.0)
    assert not s.ready and s.poll(68.0) == b"+++\r"


def test_the_emulated_modem_starts_online_and_demands_the_guard(tmp_path: Path) -> None:
    emu = ModemEmulator(tmp_path / "m", lambda t: None)
    assert _answers(emu, b"AT\r") == []  # online: a command is data
    emu = ModemEmulator(tmp_path / "m2", lambda t: None)
    assert _answers(emu, b"AT\r+++\r") == []  # no silence before +++: data too
    emu = ModemEmulator(tmp_path / "m3", lambda t: None)
    assert _answers(emu, b"+++\r") == [b"\r\nuser:1> "]
    assert not emu.online


def test_the_daemon_brings_an_online_modem_to_command_mode_and_pings(tmp_path: Path) -> None:
    from navd.drivers.transport import SerialTransport

    async def main() -> None:
        emu = ModemEmulator(tmp_path / "m", lambda t: (0.05, 75.0, 37.05, -80.66, 3.0))
        session = modem.ModemSession()
        got: list = []
        dec = modem.ModemDecoder()

        def seen(rec: object) -> None:
            got.append(rec)
            if isinstance(rec, modem.ModemMode | modem.ModemReply):
                session.seen(rec)

        tr = SerialTransport(str(emu.path), 9600, dec, seen)
        tr.start()
        while not tr.health.connected:
            await asyncio.sleep(0.01)
        loop = asyncio.get_running_loop()
        session.opened(loop.time())
        t_end = loop.time() + 8.0
        while not session.ready and loop.time() < t_end:
            data = session.poll(loop.time())
            if data:
                tr.write(data)
            await asyncio.sleep(0.05)
        assert session.ready and not emu.online
        tr.write(modem.encode_range(2))
        while not any(isinstance(r, modem.ModemRange) for r in got) and loop.time() < t_end:
            await asyncio.sleep(0.05)
        assert any(isinstance(r, modem.ModemRange) for r in got)
        await tr.stop()
        emu.close()

    asyncio.run(main())


# LSTS DUNE, src/Sensors/Keller/Task.cpp: F69 reads the serial number (a big-endian
# uint32) after F48; exception 32 means not initialised (answered with F48); RS-485
# adapters may echo every request ("Serial Port - Local Echo").


def test_keller_serial_number(tmp_path: Path) -> None:
    dec = keller.KellerDecoder(250)
    assert dec.request_serial() == bytes.fromhex("fa 45 e3 82")
    (rec,) = dec.feed(bytes.fromhex("fa 45 00 01 e2 40 1e c1"), 1.0)
    assert rec == keller.SerialNumber(1.0, 123456)
    emu = KellerEmulator(tmp_path / "k", addr=250, serial_number=123456)
    assert _answers(emu, bytes.fromhex("fa 45 e3 82")) == [bytes.fromhex("fa 45 00 01 e2 40 1e c1")]


def test_keller_power_blip_gives_exception_32_until_f48(tmp_path: Path) -> None:
    emu = KellerEmulator(tmp_path / "k", addr=250)
    emu.power_blip()
    read = keller.encode_read_float(250, keller.CH_PRESSURE)
    (frame,) = _answers(emu, read)
    assert frame == bytes.fromhex("fa c9 20 79 06")
    dec = keller.KellerDecoder(250)
    dec.request(keller.CH_PRESSURE)
    (err,) = dec.feed(frame, 1.0)
    assert isinstance(err, DeviceError) and err.code == keller.E_NOT_INITIALISED
    assert err.send == keller.encode_init(250)  # what the daemon writes back
    emu = KellerEmulator(tmp_path / "k2", addr=250)
    emu.power_blip()
    answers = _answers(emu, keller.encode_init(250) + read)
    assert len(answers) == 2 and answers[1][1] == keller.F_READ_FLOAT  # reading again


def test_keller_local_echo_is_dropped_not_counted(tmp_path: Path) -> None:
    from navd.drivers.transport import SerialTransport

    async def main() -> None:
        emu = KellerEmulator(tmp_path / "k", addr=1, local_echo=True)
        emu.pressure_bar = 1.5
        dec = keller.KellerDecoder(1, local_echo=True)
        got: list = []
        tr = SerialTransport(str(emu.path), 9600, dec, got.append)
        tr.start()
        while not tr.health.connected:
            await asyncio.sleep(0.01)
        tr.write(dec.request_init())
        tr.write(dec.request_serial())
        for _ in range(5):
            tr.write(dec.request(keller.CH_PRESSURE))
            await asyncio.sleep(0.05)
        t_end = asyncio.get_running_loop().time() + 5.0
        while sum(isinstance(r, Pressure) for r in got) < 5 or not any(
            isinstance(r, keller.SerialNumber) for r in got
        ):
            assert asyncio.get_running_loop().time() < t_end, "answers not in time"
            await asyncio.sleep(0.02)
        await tr.stop()
        emu.close()
        assert [r.bar for r in got if isinstance(r, Pressure)] == [1.5] * 5
        assert any(isinstance(r, keller.SerialNumber) for r in got)
        assert dec.stats.bad_checksum == 0 and dec.stats.skipped_bytes == 0
        assert dec.stats.reasons["echo"] == 7

    asyncio.run(main())


# LSTS DUNE, src/Sensors/Microstrain3DMGX3/Task.cpp: "E5 00 addr_hi addr_lo" reads an
# EEPROM word (a 5-byte answer); the hard-iron offsets are three float32 from 0x0400;
# "FE 9E 3A" is a soft reset, with no answer.


def test_gx3_hard_iron_is_read_from_eeprom(tmp_path: Path) -> None:
    dec = ahrs.AhrsDecoder()
    reads = dec.request_hard_iron()
    assert reads[:4] == bytes.fromhex("e5 00 04 00") and len(reads) == 24
    emu = AhrsEmulator(tmp_path / "a")
    emu.hard_iron = (0.25, -0.5, 0.125)
    frames = _answers(emu, reads)
    assert frames[0] == bytes.fromhex("e5 00 00 00 e5")  # 0.25 is 3E80 0000: low word first
    words = [r for f in frames for r in dec.feed(f, 1.0)]
    assert [w.address for w in words] == [0x400 + 2 * i for i in range(6)]
    assert ahrs.hard_iron([w.value for w in words]) == (0.25, -0.5, 0.125)


def test_gx3_hard_iron_word_order_is_dunes() -> None:
    """The words DUNE's task writes for (12.5, -3.25, 0): 12.5 is 0x41480000, -3.25
    0xC0500000, each float's low 16 bits at the lower address."""
    words = [0x0000, 0x4148, 0x0000, 0xC050, 0x0000, 0x0000]
    assert ahrs.hard_iron(words) == (12.5, -3.25, 0.0)
    assert ahrs.hard_iron([0x1234, 0x3F80, 0, 0, 0, 0])[0] == pytest.approx(1.0, abs=1e-3)


def test_gx3_soft_reset_stops_the_stream(tmp_path: Path) -> None:
    assert ahrs.encode_soft_reset() == bytes.fromhex("fe 9e 3a")
    emu = AhrsEmulator(tmp_path / "a")
    emu.streaming = True
    assert _answers(emu, ahrs.encode_soft_reset()) == []
    assert emu.resets == 1 and not emu.streaming


def test_capture_records_a_device_as_navd_asks_it(tmp_path: Path) -> None:
    """``navd capture pressure``: F48, F69 and F73 polls go out as in service, and the
    bytes that came back decode again (the procedure of docs/protocols.md)."""
    import threading

    from navd.daemon.capture import capture, raw_frames

    loop = asyncio.new_event_loop()
    emu_ready = threading.Event()
    holder: dict = {}

    def serve() -> None:
        asyncio.set_event_loop(loop)

        async def start() -> None:
            holder["emu"] = KellerEmulator(tmp_path / "pressure", addr=1)
            holder["emu"].pressure_bar = 1.2
            emu_ready.set()

        loop.run_until_complete(start())
        loop.run_forever()

    th = threading.Thread(target=serve, daemon=True)
    th.start()
    emu_ready.wait(5.0)
    cfg = config_from_dict({"devices": {"pressure": {"port": str(tmp_path / "pressure")}}})
    path = capture(cfg, "pressure", 2.0, tmp_path / "cap")
    loop.call_soon_threadsafe(holder["emu"].close)
    loop.call_soon_threadsafe(loop.stop)
    th.join(5.0)
    assert path is not None
    frames = raw_frames(path, "pressure")
    dec = keller.KellerDecoder(1)
    dec.request_init()
    recs = [r for t, b in frames for r in dec.feed(b, t)]
    assert any(isinstance(r, keller.SerialNumber) for r in recs)
    # the polls were answered: the readings are in the capture
    dec2 = keller.KellerDecoder(1)
    for _ in range(50):
        dec2.request(keller.CH_PRESSURE)
    readings = [r for t, b in frames for r in dec2.feed(b, t) if isinstance(r, Pressure)]
    assert len(readings) >= 10 and all(r.bar == pytest.approx(1.2) for r in readings)


def test_received_data_lines_do_not_confuse_the_parser() -> None:
    """Goby3: received data arrives as DATA(NNNN):..., Source/Destination, CRC/SNR and
    <EOP> lines; they are the modem's own output, not garbage, and carry no range."""
    dec = modem.ModemDecoder()
    text = (
        b"DATA(0004):48656c6c\r\nSource:001  Destination:002\r\n"
        b"CRC:Pass MPD:03.2 SNR:31.3 AGC:91 SPD:+00.0 CCERR:013\r\n<EOP>\r\n"
    )
    assert dec.feed(text, 1.0) == []
    assert dec.stats.skipped_bytes == 0
    (rng,) = dec.feed(GOBY_RANGE + b"OK\r\n", 2.0)[:1]
    assert rng.range_m == 1499.6


def test_gx3_a_new_hard_iron_read_supersedes_unanswered_ones() -> None:
    dec = ahrs.AhrsDecoder()
    dec.request_hard_iron()  # never answered (the unit was stalled)
    dec.request_eeprom(0x0500)
    dec.request_hard_iron()
    word = bytes([0xE5, 0x3E, 0x80])
    (w,) = dec.feed(word + (sum(word) & 0xFFFF).to_bytes(2, "big"), 1.0)
    assert w.address == ahrs.HARD_IRON_ADDR


@pytest.mark.parametrize("size", [1, 16, 256, 4096])
def test_the_modem_decoder_reads_the_same_at_any_read_size(size: int) -> None:
    """The ATM-900's lines as Goby's driver knows them, handed over in reads of ``size``
    bytes as a UART or the 50 ms read window does: the same records, the same modes and
    replies as in one read.  (No public capture of an ATM-900 exists to replay here.)"""
    text = (
        b"Command '+++' not found\r\n\r\nuser:1> "
        + b"TX time 12:00:00\r\n"
        + GOBY_RANGE
        + b"Remote Lat: 37.0490112 Lon: -80.6670001 Depth: 3.0\r\nOK\r\n"
        + b"Response Not Received.\r\nERROR\r\nCONNECT 2400\r\nuser:1 Lowpower> "
    )
    whole = modem.ModemDecoder().feed(text, 1.0)
    dec = modem.ModemDecoder()
    parts: list[object] = []
    for i in range(0, len(text), size):
        parts += dec.feed(text[i : i + size], 1.0)
    assert parts == whole
    assert [type(r).__name__ for r in whole].count("ModemRange") == 1
    kinds = [getattr(r, "status", getattr(r, "mode", None)) for r in whole]
    assert kinds == [
        "command", "command", None, "ok", "no_reply", "refused", "online", "lowpower"
    ]  # fmt: skip
    assert dec.stats.skipped_bytes == 0
