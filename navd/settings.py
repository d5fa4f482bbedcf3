"""The settings navd runs with: typed, validated, every key defaulted.

The schema *is* the dataclasses below: each field's type and default is the
contract, and ``metadata`` carries its allowed range.  :func:`config_from_dict` walks
them, so an unknown key, a wrong type, a non-finite or out-of-range value is a
:class:`ConfigError` whose message names the key (``navigation.speed.rpm_per_mps``).

This is a foundation module: no files, no YAML.  Reading a config file with its
overlays is :mod:`navd.config`, above it.
"""

from __future__ import annotations

import typing
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Literal

from navd import endpoints, validation
from navd.acoustics import SoundSpeed
from navd.utc import utc_seconds
from navd.validation import Invalid, T
from navd.validation import number as _num

__all__ = ["ConfigError", "Config", "config_from_dict", "Beacon", "build", "deep_merge"]


class ConfigError(Invalid):
    """A configuration problem; ``str()`` is one line naming the file and key."""


@dataclass(frozen=True, slots=True)
class SpeedConfig:
    # linear RPM-to-surge map from a speed trial; below 1 any RPM would be a ship's speed
    rpm_per_mps: float = _num(910.0, lo=1.0, hi=1e6)
    # added to rpm / rpm_per_mps while the propeller turns (navd calibrate speed)
    offset_mps: float = _num(0.0, lo=-2.0, hi=2.0)


@dataclass(frozen=True, slots=True)
class SoundSpeedConfig:
    model: Literal["coppens", "mackenzie", "fixed"] = "coppens"
    temperature_c: float = _num(10.0, lo=-5.0, hi=45.0)
    salinity_ppt: float = _num(0.2, lo=0.0, hi=50.0)
    fixed_mps: float = _num(1500.0, lo=1300.0, hi=1700.0)
    modem_mps: float = _num(1500.0, lo=1300.0, hi=1700.0)
    # how far the water column's mean sound speed may be from the one configured (one
    # sigma): a surface temperature 1.7 C off the column's mean is about 5 m/s
    std_mps: float = _num(5.0, lo=0.0, hi=100.0)

    def model_obj(self) -> SoundSpeed:
        return SoundSpeed(
            self.model, self.temperature_c, self.salinity_ppt, self.fixed_mps, self.modem_mps
        )


@dataclass(frozen=True, slots=True)
class NoiseConfig:
    range_std_m: float = _num(3.0, gt=0.0)
    heading_std_deg: float = _num(2.0, gt=0.0)
    speed_std_mps: float = _num(0.1, gt=0.0)
    position_init_std_m: float = _num(5.0, gt=0.0)
    current_init_std_mps: float = _num(0.3, gt=0.0)
    # default-mode additions (the thesis mode ignores them)
    heading_bias_init_std_deg: float = _num(5.0, gt=0.0)
    speed_scale_init_std: float = _num(0.1, gt=0.0)
    current_walk_mps_per_sqrt_s: float = _num(0.002, lo=0.0)
    heading_bias_walk_deg_per_sqrt_s: float = _num(0.01, lo=0.0)
    speed_scale_walk_per_sqrt_s: float = _num(0.0005, lo=0.0)
    input_corr_s: float = _num(2.0, gt=0.0)  # correlation time of heading/speed errors
    gps_std_m: float = _num(3.0, gt=0.0)
    thesis_position_walk_m_per_sqrt_s: float = _num(0.3, lo=0.0)
    thesis_current_walk_mps_per_sqrt_s: float = _num(0.0, lo=0.0)


@dataclass(frozen=True, slots=True)
class GateConfig:
    chi2: float = _num(9.0, gt=0.0)  # innovation gate on nu^2 / S (9 = 3 sigma)
    # Multipath makes ranges read long, never short: a range longer than predicted
    # gets the tighter gate (4 = 2 sigma).
    chi2_long: float = _num(4.0, gt=0.0)
    reacquire_after: int = _num(3, lo=1, hi=100)  # consecutive rejections before re-acquiring
    # A GPS fix whose innovation (from the estimate, with its covariance and the fix's
    # std) is past this chi-square on 2 degrees of freedom is refused: 25 is Fulton's
    # gamma (seed 003), a one-in-270,000 chance for a fix that fits the estimate.
    gps_chi2: float = _num(25.0, gt=0.0)
    # refused fixes that agree with each other, in a row, before they are the position
    gps_agree: int = _num(4, lo=2, hi=100)
    max_beacon_speed_mps: float = _num(8.0, gt=0.0)  # faster apparent beacon motion = corrupt
    max_range_m: float = _num(10000.0, gt=0.0)


@dataclass(frozen=True, slots=True)
class GpsConfig:
    warmup_s: float = _num(30.0, lo=0.0)  # after re-acquiring at the surface, fixes are poor
    warmup_std_m: float = _num(15.0, gt=0.0)
    max_hdop: float = _num(10.0, gt=0.0)


@dataclass(frozen=True, slots=True)
class DvlConfig:
    """DVL dead reckoning and its error prediction (seed 002), used when velocity records come."""

    velocity_error_frac: float = _num(0.05, lo=0.0, hi=1.0)
    attitude_error_deg: float = _num(3.0, lo=0.0, hi=45.0)
    max_accel_mps2: float = _num(0.5, gt=0.0)
    max_rejections: int = _num(5, lo=0, hi=1000)
    error_limit_m: float = _num(50.0, gt=0.0)


@dataclass(frozen=True, slots=True)
class IntegrityConfig:
    """When an estimate is ``degraded`` or ``lost`` (navd/filter/integrity.py)."""

    window: int = _num(10, lo=3, hi=100)  # ranges in the consistency test
    degraded_std_m: float = _num(25.0, gt=0.0)
    lost_std_m: float = _num(100.0, gt=0.0)
    # refused ranges or fixes in a row (whatever the window holds) for degraded, and lost
    degraded_refused: int = _num(3, lo=1, hi=1000)
    lost_refused: int = _num(8, lo=1, hi=1000)


@dataclass(frozen=True, slots=True)
class TideConfig:
    """The site's tidal stream as the crew's prediction gives it for the mission's day
    (navd/filter/tide.py): a rectilinear semidiurnal stream.  No amplitude: none."""

    amplitude_mps: float = _num(0.0, lo=0.0, hi=5.0)  # the speed of maximum flood
    toward_deg: float = _num(0.0, lo=-360.0, hi=360.0)  # the flood's direction, true
    # an instant of maximum flood, ISO 8601 with its zone (2016-04-14T15:20:00Z)
    max_flood_utc: str = validation.text(
        "",
        r"(\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}(:\d{2}(\.\d{1,9})?)?(Z|[+-]\d{2}:?\d{2}))?",
        "an ISO 8601 time with its zone, such as 2016-04-14T15:20:00Z",
    )
    period_s: float = _num(44714.0, lo=3600.0, hi=200000.0)  # M2, the principal lunar semidiurnal
    # how far the prediction may be off, as a fraction of its amplitude (its errors of
    # size, time and direction together): the turning stream the ellipse still allows for
    error_fraction: float = _num(0.5, gt=0.0, hi=2.0)


@dataclass(frozen=True, slots=True)
class NavigationConfig:
    filter: Literal["default", "thesis", "vlbl"] = "default"
    rate_hz: float = _num(10.0, lo=1.0, hi=100.0)
    magnetic_declination_deg: float = _num(0.0, lo=-180.0, hi=180.0)
    surface_depth_m: float = _num(0.3, lo=0.0, hi=20.0)
    stale_input_s: float = _num(1.0, gt=0.0)
    max_gap_s: float = _num(600.0, gt=0.0)  # a longer silence in the input restarts the filter
    # the fastest current this site can have (strong tidal races reach about 3 m/s): a
    # learned current is held below it, a re-acquisition implying more is refused, and
    # the default mode's ellipse allows for a tidal stream this strong (navd/filter/bank.py)
    max_current_mps: float = _num(2.0, gt=0.0, hi=10.0)
    # the compass's deviation curve A, B, C, D, E in degrees (navd/filter/compass.py),
    # as ``navd calibrate compass`` fits it; empty: none
    compass_deviation_deg: list[float] = field(
        default_factory=list, metadata={"lo": -45.0, "hi": 45.0}
    )
    speed: SpeedConfig = field(default_factory=SpeedConfig)
    sound_speed: SoundSpeedConfig = field(default_factory=SoundSpeedConfig)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    gate: GateConfig = field(default_factory=GateConfig)
    gps: GpsConfig = field(default_factory=GpsConfig)
    dvl: DvlConfig = field(default_factory=DvlConfig)
    integrity: IntegrityConfig = field(default_factory=IntegrityConfig)
    tide: TideConfig = field(default_factory=TideConfig)


@dataclass(frozen=True, slots=True)
class Beacon:
    lat: float | None = _num(None, lo=-90.0, hi=90.0)
    lon: float | None = _num(None, lo=-180.0, hi=180.0)
    depth: float = _num(0.0, lo=0.0, hi=11000.0)
    turnaround_s: float = _num(0.0, lo=0.0, hi=10.0)
    # one-sigma horizontal error of the position the beacon reports (its GPS, the
    # transducer's offset); the default filter estimates it as a slowly varying offset
    position_std_m: float = _num(5.0, lo=0.0, hi=1000.0)
    # how slowly a reported position's error wanders (GPS: minutes); a configured one's is
    # constant whatever this says (docs/replay.md, "Beacons whose position error is not a state")
    position_corr_s: float = _num(120.0, gt=0.0)
    # replies without a position (the boat's location line down): the beacon is
    # predicted from its recent reports for this long, then such ranges are refused
    predict_max_s: float = _num(300.0, lo=0.0, hi=3600.0)


@dataclass(frozen=True, slots=True)
class SiteConfig:
    name: str = "unnamed"
    water_density_kgm3: float = _num(1000.0, lo=990.0, hi=1050.0)
    surface_pressure_bar: float = _num(1.01325, lo=0.8, hi=1.2)
    # take the surface pressure from readings while GPS has a fix (before each dive)
    surface_pressure_from_gps: bool = True
    gravity_mps2: float = _num(9.80665, lo=9.7, hi=9.9)
    surface_altitude_m: float | None = _num(None, lo=-200.0, hi=5000.0)
    # the geoid above the ellipsoid here (EGM96 or the chart's), for receivers that give
    # only a height above sea level: their fixes' ellipsoidal height is MSL plus this
    geoid_separation_m: float | None = _num(None, lo=-150.0, hi=150.0)


@dataclass(frozen=True, slots=True)
class SerialPortConfig:
    port: str = ""  # e.g. /dev/navd-ahrs (udev name); required by navd run when enabled
    baudrate: int = _num(9600, lo=300, hi=4_000_000)
    enabled: bool = True

    @property
    def url(self) -> str:
        """What the transport opens."""
        return self.port


@dataclass(frozen=True, slots=True)
class GpsDevice(SerialPortConfig):
    # serial: NMEA on ``port``; gpsd: gpsd's JSON from ``host``:``gpsd_port``, for a
    # receiver shared with chrony (docs/protocols.md)
    source: Literal["serial", "gpsd"] = "serial"
    host: str = "127.0.0.1"
    gpsd_port: int = _num(2947, lo=1, hi=65535)

    @property
    def url(self) -> str:
        """What the transport opens: the serial port, or gpsd's socket."""
        if self.source == "gpsd":
            host = f"[{self.host}]" if ":" in self.host else self.host
            return f"socket://{host}:{self.gpsd_port}"
        return self.port


@dataclass(frozen=True, slots=True)
class AhrsDevice(SerialPortConfig):
    baudrate: int = _num(115200, lo=300, hi=4_000_000)
    rate_hz: float = _num(20.0, gt=0.0, hi=1000.0)  # twice the filter rate


@dataclass(frozen=True, slots=True)
class PolledDevice(SerialPortConfig):
    poll_hz: float = _num(10.0, gt=0.0, hi=100.0)


@dataclass(frozen=True, slots=True)
class PressureDevice(PolledDevice):
    address: int = _num(1, lo=0, hi=255)  # Keller bus address
    local_echo: bool = False  # the RS-485 adapter hands every request back (it is dropped)


@dataclass(frozen=True, slots=True)
class MotorDevice(PolledDevice):
    pole_pairs: int = _num(1, lo=1, hi=64)  # motor pole pairs (Castle eRPM to RPM)
    device_id: int = _num(0, lo=0, hi=127)  # Castle Serial Link device id (request byte 0x80 | id)


@dataclass(frozen=True, slots=True)
class ModemDevice(SerialPortConfig):
    remote_address: int = _num(2, lo=0, hi=255)  # the UDB-9400's modem address
    beacon: str = "udb"  # the beacon name its ranges carry
    # a ping takes a round trip and the modem's own turnaround: faster is a typo, and
    # would flood the modem (1e-6 once gave 122,000 ATRX writes in 8 s)
    ping_interval_s: float = _num(10.0, lo=1.0, hi=3600.0)
    reply_timeout_s: float = _num(8.0, lo=0.5, hi=600.0)
    # the modem's own wait for the remote before it prints "Response Not Received."
    # (a modem setting, 2 to 99.5 s): navd's reply_timeout_s must outlast it
    modem_timeout_s: float = _num(4.0, lo=2.0, hi=99.5)


@dataclass(frozen=True, slots=True)
class DevicesConfig:
    ahrs: AhrsDevice = field(default_factory=AhrsDevice)
    gps: GpsDevice = field(default_factory=GpsDevice)
    pressure: PressureDevice = field(default_factory=PressureDevice)
    motor: MotorDevice = field(default_factory=MotorDevice)
    modem: ModemDevice = field(default_factory=ModemDevice)


#: the devices navd knows, by the name of their config section: the daemon's devices,
#: ``navd capture`` and the bench's emulators are all keyed by these
DEVICE_NAMES: tuple[str, ...] = tuple(f.name for f in fields(DevicesConfig))


def device_config(devices: DevicesConfig, name: str) -> SerialPortConfig:
    """One device's section of ``devices``."""
    section: SerialPortConfig = getattr(devices, name)
    return section


@dataclass(frozen=True, slots=True)
class ZenohConfig:
    mode: Literal["peer", "client"] = "peer"
    listen: list[str] = field(default_factory=lambda: ["tcp/127.0.0.1:7447"])
    connect: list[str] = field(default_factory=list)
    config_file: str | None = None  # a zenoh JSON5 file; the keys above then override it
    multicast_scouting: bool = False
    # listen endpoints are loopback only, unless these say otherwise: an address of a
    # network of the vehicle (an autopilot on another computer), or every interface
    listen_beyond_loopback: bool = False
    listen_on_every_interface: bool = False


@dataclass(frozen=True, slots=True)
class LogConfig:
    # empty: $LOGS_DIRECTORY under systemd (LogsDirectory=navd: /var/log/navd), else
    # ./navd-log, for a development run (resolved by log_dir)
    dir: str = ""
    rotate_mb: float = _num(64.0, lo=1.0, hi=100_000.0)  # smaller makes files by the second
    fsync_s: float = _num(1.0, lo=0.1, hi=60.0)
    raw_bytes: bool = True  # also log every byte off the serial ports
    # what one device's raw bytes may take, per second: a babbling device must not fill
    # the disk (at full speed about 13 MB/s); the excess is counted, not logged
    raw_budget_bytes_per_s: float = _num(20_000.0, lo=100.0, hi=1e8)
    # the log directory is kept under this: the oldest files go first (0 keeps all)
    keep_mb: float = _num(20_000.0, lo=0.0, hi=1e7)


@dataclass(frozen=True, slots=True)
class CheckpointConfig:
    """The navigation state kept on disk, for a restart while submerged (daemon/checkpoint.py)."""

    # empty: $STATE_DIRECTORY under systemd (StateDirectory=navd: /var/lib/navd); with
    # neither, no checkpoint is kept (a development run)
    dir: str = ""
    every_s: float = _num(1.0, lo=0.1, hi=60.0)
    # an older checkpoint is not resumed: the vehicle may be anywhere by then
    max_age_s: float = _num(300.0, lo=0.0, hi=86_400.0)
    # how fast the vehicle may have moved while navd was down (its speed and the
    # current): the position's std grows by this times the checkpoint's age
    drift_mps: float = _num(3.0, gt=0.0, hi=50.0)


@dataclass(frozen=True, slots=True)
class VehicleConfig:
    name: str = "690s"


@dataclass(frozen=True, slots=True)
class Config:
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    beacons: dict[str, Beacon] = field(default_factory=dict)
    site: SiteConfig = field(default_factory=SiteConfig)
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    devices: DevicesConfig = field(default_factory=DevicesConfig)
    zenoh: ZenohConfig = field(default_factory=ZenohConfig)
    log: LogConfig = field(default_factory=LogConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)


def check_for_run(cfg: Config) -> None:
    """What ``navd run`` needs beyond a valid file: a port for every enabled device."""
    for name in DEVICE_NAMES:
        dev = device_config(cfg.devices, name)
        if isinstance(dev, GpsDevice) and dev.source == "gpsd":
            continue  # gpsd has the port
        if dev.enabled and not dev.port:
            raise ConfigError(f"devices.{name}.port: required by navd run (or enabled: false)")
    if not cfg.vehicle.name.replace("-", "").replace("_", "").isalnum():
        raise ConfigError("vehicle.name: letters, digits, - and _ only (it is a zenoh key)")


def _fail(path: str, msg: str) -> typing.NoReturn:
    raise ConfigError(f"{path}: {msg}")


def build(cls: type[T], data: object, path: str = "") -> T:
    """Validate a mapping into the dataclass ``cls`` (used for scenario files too)."""
    try:
        return validation.build(cls, data, path)
    except ConfigError:
        raise
    except Invalid as exc:
        raise ConfigError(str(exc)) from None


def config_from_dict(data: object) -> Config:
    """Validate a parsed YAML document into a :class:`Config`."""
    cfg = build(Config, data, "")
    z = cfg.zenoh
    for i, ep in enumerate(z.listen):
        # commands reach the vehicle through this: loopback, unless the config says more
        why = endpoints.listen_problem(ep, z.listen_beyond_loopback, z.listen_on_every_interface)
        if why is not None:
            _fail(f"zenoh.listen[{i}]", why)
    for i, ep in enumerate(z.connect):
        try:
            endpoints.parse(ep)
        except ValueError as exc:
            _fail(f"zenoh.connect[{i}]", str(exc))
    n = len(cfg.navigation.compass_deviation_deg)
    if n not in (0, 5):
        _fail(
            "navigation.compass_deviation_deg",
            f"expected the 5 coefficients A, B, C, D, E (or none), got {n}",
        )
    tide = cfg.navigation.tide
    if tide.amplitude_mps > 0.0 and utc_seconds(tide.max_flood_utc) is None:
        _fail(
            "navigation.tide.max_flood_utc",
            f"{validation.show(tide.max_flood_utc)} is not an ISO 8601 time with its zone (such "
            "as 2016-04-14T15:20:00Z): a tide with an amplitude needs the time of a maximum flood",
        )
    m = cfg.devices.modem
    if m.reply_timeout_s <= m.modem_timeout_s:
        _fail(
            "devices.modem.reply_timeout_s",
            f"{m.reply_timeout_s:g} s does not outlast the modem's own timeout "
            f"(devices.modem.modem_timeout_s {m.modem_timeout_s:g} s): a ping would be "
            "given up while the modem still waits for its reply",
        )
    return cfg


def deep_merge(base: Mapping[str, object], over: Mapping[str, object]) -> dict[str, object]:
    """``over`` on top of ``base``: mappings merged key by key, anything else replaced.

    New mappings are made only along the paths both have; everything else is shared,
    not copied, so the time is that of walking ``over`` (whose expansion the YAML
    loader bounds), whatever aliases either holds.  Neither input is changed.
    """
    out = dict(base)
    for k, v in over.items():
        old = out.get(k)
        if isinstance(v, dict) and isinstance(old, dict):
            out[k] = deep_merge(old, v)
        else:
            out[k] = v
    return out
