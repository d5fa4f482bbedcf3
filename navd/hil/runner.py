"""``navd-hil SCENARIO --dir DIR``: the emulated vehicle, in real time, on pseudo-terminals.

Starts one emulator per device behind stable paths in DIR (``ahrs``, ``gps``,
``pressure``, ``motor``, ``modem``), writes ``DIR/navd.yaml`` (the crew's config with
those ports, a loopback zenoh endpoint and a log directory) and moves the emulators
along the simulated mission: compass, RPM, pressure and GPS from the simulated
sensors at their times, ranges from the acoustic channel when navd pings.  The truth
goes to ``DIR/truth.jsonl``; ``DIR/clock.json`` says which monotonic time was mission
time zero.  Faults can be scheduled with ``--faults FILE`` (YAML list of
``{t, device, action, value}``; actions: reconnect, disconnect, garbage, bad_checksum,
truncate, drop_reply (value: a probability), stall, unstall, gps_off, gps_on, glitch).  One
line on stderr, written once the emulators serve their ports and ``clock.json``
exists, tells a supervising script that the vehicle is up.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import signal
import sys
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import yaml

from navd import files
from navd.formats import jsonlines
from navd.hil.emulators.ahrs import AhrsEmulator
from navd.hil.emulators.base import Emulator
from navd.hil.emulators.castle import CastleEmulator
from navd.hil.emulators.gps import GpsEmulator
from navd.hil.emulators.keller import KellerEmulator
from navd.hil.emulators.modem import ModemEmulator
from navd.hil.link import modem_range_fn
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import crew_config
from navd.hil.world import simulate
from navd.records import Depth, Gps, Heading, Rpm
from navd.settings import DEVICE_NAMES, ConfigError, config_from_dict, deep_merge, device_config
from navd.validation import Invalid, build, number

_GPS_HOLD_S = 1.5  # a GPS fix older than this means the antenna went under


@dataclass(frozen=True, slots=True)
class Emulators:
    """One emulator per device, by the device's config section name."""

    ahrs: AhrsEmulator
    gps: GpsEmulator
    pressure: KellerEmulator
    motor: CastleEmulator
    modem: ModemEmulator

    def by_name(self, name: str) -> Emulator:
        emulator: Emulator = getattr(self, name)
        return emulator

    def each(self) -> list[Emulator]:
        return [self.by_name(n) for n in DEVICE_NAMES]

FaultDevice = Literal["ahrs", "gps", "pressure", "motor", "modem"]
FaultAction = Literal[
    "reconnect",
    "disconnect",
    "stall",
    "unstall",
    "gps_off",
    "gps_on",
    "online",  # the modem falls into online (data) mode, as after a CONNECT
    "power_blip",  # the pressure sensor loses power and forgets its F48
    "glitch",  # the GPS's next fixes (value: how many; default 1) at (0, 0), checksum and all
    "flood",
    "garbage",
    "bad_checksum",
    "truncate",
    "drop_reply",
    "error_reply",
]
_RATE_ACTIONS = ("garbage", "bad_checksum", "truncate", "drop_reply", "error_reply")
_ONLY_ON = {"online": "modem", "power_blip": "pressure", "glitch": "gps"}


@dataclass(frozen=True, slots=True)
class Fault:
    t: float = number(math.nan)  # seconds into the mission; required
    device: FaultDevice = "ahrs"
    action: FaultAction = "reconnect"
    # a probability for the rate actions, how many times each frame is sent for flood
    value: float = number(0.0, lo=0.0, hi=1000.0)


def check_faults(faults: object) -> list[Fault]:
    """The fault schedule, or a ConfigError naming the first bad entry."""
    if faults is None:
        return []
    if not isinstance(faults, list):
        raise ConfigError("faults: expected a list of {t, device, action, value}")
    out = []
    for i, f in enumerate(faults):
        where = f"faults[{i}]"
        try:
            if isinstance(f, dict) and "t" not in f:
                raise Invalid(f"{where}.t: missing (seconds into the mission)")
            fault = build(Fault, f, where)
        except Invalid as exc:
            raise ConfigError(str(exc)) from None
        if _ONLY_ON.get(fault.action, fault.device) != fault.device:
            raise ConfigError(f"{where}.action: {fault.action} is a {_ONLY_ON[fault.action]} fault")
        v = fault.value
        if fault.action == "flood" and not (v.is_integer() and v >= 1):
            raise ConfigError(f"{where}.value: expected how many times each frame is sent")
        if fault.action in _RATE_ACTIONS and not v <= 1.0:
            raise ConfigError(f"{where}.value: expected a probability in [0, 1]")
        out.append(fault)
    return out


def daemon_config(
    crew: Mapping[str, object],
    d: Path,
    zenoh_port: int,
    vehicle: str = "sim690s",
    connect: list[str] | None = None,
) -> dict[str, object]:
    return deep_merge(
        crew,
        {
            "vehicle": {"name": vehicle},
            "devices": {
                "ahrs": {"port": str(d / "ahrs"), "rate_hz": 20},
                "gps": {"port": str(d / "gps")},
                "pressure": {"port": str(d / "pressure"), "address": 1},
                "motor": {"port": str(d / "motor")},
                "modem": {"port": str(d / "modem"), "remote_address": 2, "beacon": "udb"},
            },
            "zenoh": {"listen": [f"tcp/127.0.0.1:{zenoh_port}"], "connect": connect or []},
            "log": {"dir": str(d / "log")},
        },
    )


class Bench:
    def __init__(
        self,
        scenario: str,
        seed: int,
        d: Path,
        zenoh_port: int,
        speed: float = 1.0,
        vehicle: str = "sim690s",
        connect: list[str] | None = None,
    ):
        self.sc = load_scenario(scenario)
        self.mission = simulate(self.sc, seed)
        self.dir = d
        self.speed = speed
        d.mkdir(parents=True, exist_ok=True)
        crew = crew_config(self.sc)
        cfg = daemon_config(crew, d, zenoh_port, vehicle, connect)
        parsed = config_from_dict(cfg)  # also proves the generated config valid
        self.site = parsed.site
        self.baud = {n: device_config(parsed.devices, n).baudrate for n in DEVICE_NAMES}
        # the emulated devices are set up as the config says the real ones are
        self.modem_timeout_s = parsed.devices.modem.modem_timeout_s
        self.motor_id = parsed.devices.motor.device_id
        self.modem_mps = parsed.navigation.sound_speed.modem_mps
        (d / "navd.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False), encoding="utf-8")
        with (d / "truth.jsonl").open("w", encoding="utf-8") as fh:
            for s in self.mission.truth:
                fh.write(jsonlines.dumps_line(asdict(s)))

    def _pressure(self, depth: float) -> float:
        s = self.site
        return s.surface_pressure_bar + s.water_density_kgm3 * s.gravity_mps2 * depth / 1e5

    async def run(
        self, stop: asyncio.Event, faults: list[Fault], banner: str = ""
    ) -> None:
        d = self.dir
        self.t0 = time.monotonic()
        clock = {"t0_monotonic": self.t0, "speed": self.speed}
        (d / "clock.json").write_bytes(jsonlines.dumps(clock))
        # every emulator paces its output at the daemon's configured line speed
        emus = self._emulators()
        gps_emu = emus.gps
        gps_emu.start()
        if banner:
            print(banner, file=sys.stderr, flush=True)  # the ports are served: vehicle up
        gps_off = False
        last_fix = -1e9
        pending = sorted(faults, key=lambda f: f.t)
        try:
            for rec in self.mission.records:
                while pending and pending[0].t <= rec.t:
                    f = pending.pop(0)
                    gps_off = self._fault(emus, f, gps_off)
                delay = self.t0 + rec.t / self.speed - time.monotonic()
                if delay > 0:
                    try:
                        await asyncio.wait_for(stop.wait(), delay)
                        return
                    except TimeoutError:
                        pass
                if isinstance(rec, Heading):
                    emus.ahrs.yaw_deg = rec.deg
                elif isinstance(rec, Rpm):
                    emus.motor.rpm = rec.rpm
                elif isinstance(rec, Depth):
                    emus.pressure.pressure_bar = self._pressure(rec.m)
                elif isinstance(rec, Gps):
                    if rec.fix and not gps_off:
                        gps_emu.lat, gps_emu.lon, gps_emu.alt_msl = rec.lat, rec.lon, rec.alt or 0.0
                        gps_emu.hdop = rec.hdop or 1.0
                        last_fix = rec.t
                    else:
                        gps_emu.lat = gps_emu.lon = None
                if rec.t - last_fix > _GPS_HOLD_S:
                    gps_emu.lat = gps_emu.lon = None
            await stop.wait()
        finally:
            for e in emus.each():
                e.close()

    def _emulators(self) -> Emulators:
        """Every device's emulator, paced at the daemon's configured line speed and set up
        as the config says the real device is."""
        d, b = self.dir, self.baud
        return Emulators(
            ahrs=AhrsEmulator(d / "ahrs", seed=1, baudrate=b["ahrs"]),
            gps=GpsEmulator(d / "gps", seed=2, baudrate=b["gps"]),
            pressure=KellerEmulator(d / "pressure", addr=1, seed=3, baudrate=b["pressure"]),
            motor=CastleEmulator(d / "motor", seed=4, baudrate=b["motor"], device_id=self.motor_id),
            modem=ModemEmulator(
                d / "modem",
                modem_range_fn(self.mission, self.t0),
                seed=5,
                timeout_s=self.modem_timeout_s,
                sound_speed_mps=self.modem_mps,
                baudrate=b["modem"],
            ),
        )

    @staticmethod
    def _fault(emus: Emulators, f: Fault, gps_off: bool) -> bool:
        e: Any = emus.by_name(f.device)  # an action the device has not is a scenario error
        action, value = f.action, f.value
        if action == "reconnect":
            e.port.reconnect()
        elif action == "disconnect":
            e.port.disconnect()
        elif action in _RATE_ACTIONS:
            setattr(e.faults, action, float(value))
        elif action == "flood":
            e.faults.flood = int(value)
        elif action == "stall":
            e.faults.stalled = True
        elif action == "unstall":
            e.faults.stalled = False
        elif action == "online":
            e.go_online()
        elif action == "power_blip":
            e.power_blip()
        elif action == "glitch":
            e.glitches = int(value or 1)
        elif action == "gps_off":
            return True
        elif action == "gps_on":
            return False
        else:
            raise ConfigError(f"faults: unknown action {action!r}")
        return gps_off


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="navd-hil",
        description="The emulated vehicle: one emulator per device on a pseudo-terminal, "
        "moved along a simulated mission in real time, and a navd.yaml to run navd against them.",
    )
    p.add_argument("scenario", help="scenario name (navd-sim --list) or YAML path")
    p.add_argument("--seed", type=int, default=1, help="random seed of the sensor errors")
    p.add_argument("--dir", required=True, help="directory for the ptys, navd.yaml and truth")
    p.add_argument("--zenoh-port", type=int, default=7447, help="port navd's zenoh listens on")
    p.add_argument("--faults", help="YAML list of scheduled faults {t, device, action, value}")
    p.add_argument("--speed", type=float, default=1.0, help="time warp (1: real time)")
    p.add_argument("--vehicle", default="sim690s", help="vehicle name (the zenoh key auv/NAME)")
    p.add_argument(
        "--zenoh-connect",
        action="append",
        metavar="ENDPOINT",
        help="the daemon also connects here (a zenoh router, for a fleet)",
    )
    args = p.parse_args(argv)
    try:
        faults = check_faults(files.load_yaml(args.faults)) if args.faults else []
        bench = Bench(
            args.scenario,
            args.seed,
            Path(args.dir),
            args.zenoh_port,
            args.speed,
            args.vehicle,
            args.zenoh_connect,
        )
    except (ConfigError, OSError, files.FileRefused) as exc:
        print(f"navd-hil: {exc}", file=sys.stderr)
        return 2

    async def amain() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, stop.set)
        banner = f"navd-hil: {bench.sc.name} on {args.dir} ({bench.mission.truth[-1].t:.0f} s)"
        await bench.run(stop, faults, banner)

    asyncio.run(amain())
    return 0


if __name__ == "__main__":
    sys.exit(main())
