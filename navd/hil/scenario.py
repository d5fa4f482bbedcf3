"""Scenario files (``navd/hil/scenarios/*.yaml``): the world a simulated mission happens in.

Validated like the navd config (same loader): an unknown key or a bad value is a
one-line error naming it.  ``config`` is a navd configuration fragment written
out beside the simulated log: only what a crew would know and set (site,
declination, speed trial, sound speed, beacon depth), never the truth's errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from navd import files
from navd.settings import ConfigError, build


def _f(default: float | None, **kw: float) -> Any:
    return field(default=default, metadata=kw)


@dataclass(frozen=True, slots=True)
class Leg:
    heading_deg: float = _f(0.0, lo=-360.0, hi=360.0)  # true heading
    duration_s: float = _f(60.0, gt=0.0)
    speed_mps: float | None = _f(None, lo=0.0, hi=5.0)
    # the leg's depth, when not the vehicle's (0: a surfacing for GPS)
    depth_m: float | None = _f(None, lo=0.0, hi=500.0)


@dataclass(frozen=True, slots=True)
class Vehicle:
    lat: float = _f(0.0, lo=-89.0, hi=89.0)
    lon: float = _f(0.0, lo=-180.0, hi=180.0)
    speed_mps: float = _f(1.1, gt=0.0, hi=5.0)
    depth_m: float = _f(1.0, gt=0.0, hi=500.0)
    dive_rate_mps: float = _f(0.3, gt=0.0)
    turn_rate_deg_s: float = _f(10.0, gt=0.0)
    surface_before_s: float = _f(60.0, lo=0.0)
    surface_after_s: float = _f(60.0, lo=0.0)
    legs: list[Leg] = field(default_factory=lambda: [Leg()])
    # run at the surface first, with GPS (a calibration circle or lawnmower)
    surface_legs: list[Leg] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class Current:
    speed_mps: float = _f(0.0, lo=0.0, hi=3.0)
    toward_deg: float = _f(0.0, lo=-360.0, hi=360.0)
    tidal_amplitude_mps: float = _f(0.0, lo=0.0, hi=3.0)  # added along the mean direction
    tidal_period_s: float = _f(44714.0, gt=0.0)  # M2
    tidal_phase_deg: float = _f(0.0, lo=-360.0, hi=360.0)  # of the tide at t = 0
    veer_deg_per_hour: float = _f(0.0, lo=-360.0, hi=360.0)


@dataclass(frozen=True, slots=True)
class Sensors:
    declination_deg: float = _f(0.0, lo=-90.0, hi=90.0)
    compass_bias_deg: float = _f(0.0, lo=-45.0, hi=45.0)  # unknown to the filter
    # a deviation curve A, B, C, D, E (navd/filter/compass.py) of the magnetic heading
    compass_deviation_deg: list[float] = field(
        default_factory=list, metadata={"lo": -45.0, "hi": 45.0}
    )
    compass_noise_deg: float = _f(1.0, lo=0.0)
    rpm_per_mps: float = _f(910.0, gt=0.0)  # the true map; the config has the trial's
    rpm_noise: float = _f(5.0, lo=0.0)
    depth_noise_m: float = _f(0.02, lo=0.0)
    gps_std_m: float = _f(2.5, lo=0.0)
    gps_acquire_s: float = _f(5.0, lo=0.0)  # no fix for this long after surfacing
    gps_warmup_s: float = _f(30.0, lo=0.0)  # fixes poor (decaying error) for this long
    gps_warmup_std_m: float = _f(15.0, lo=0.0)
    rate_hz: float = _f(10.0, gt=0.0, hi=100.0)
    dvl: bool = False  # a bottom-locked DVL (velocity records) and full attitude records
    dvl_scale_error: float = _f(0.01, lo=-0.5, hi=0.5)
    dvl_noise_mps: float = _f(0.01, lo=0.0)
    dvl_spike_prob: float = _f(0.01, lo=0.0, hi=1.0)


@dataclass(frozen=True, slots=True)
class Boat:
    north_m: float = _f(30.0)  # start, relative to the vehicle's start
    east_m: float = _f(0.0)
    speed_mps: float = _f(0.0, lo=0.0, hi=10.0)
    heading_deg: float = _f(0.0, lo=-360.0, hi=360.0)
    drifts_with_current: bool = True
    wander_mps: float = _f(0.05, lo=0.0)  # random course changes of a boat holding station
    # how fast its course wanders (a random walk): a boat holding station turns every
    # way, one motoring on a line holds its course within a few degrees
    course_wander_deg_per_sqrt_s: float = _f(20.0, lo=0.0)
    gps_std_m: float = _f(7.0, lo=0.0)  # per axis (10 m 2D RMS in Claytor Lake)
    gps_corr_s: float = _f(60.0, gt=0.0)
    transducer_depth_m: float = _f(3.0, lo=0.0)
    swing_m: float = _f(2.0, lo=0.0)  # the transducer swinging on its rope


@dataclass(frozen=True, slots=True)
class Transponder:
    """A fixed LBL transponder, placed relative to the vehicle's start."""

    name: str = "t1"
    north_m: float = _f(0.0)
    east_m: float = _f(0.0)
    depth_m: float = _f(0.0, lo=0.0, hi=11000.0)
    turnaround_s: float = _f(0.0, lo=0.0, hi=10.0)
    survey_std_m: float = _f(0.5, lo=0.0)  # how well its position was surveyed


@dataclass(frozen=True, slots=True)
class Acoustics:
    ping_interval_s: float = _f(10.0, gt=0.0)
    range_noise_m: float = _f(1.0, lo=0.0)
    drop_prob: float = _f(0.15, lo=0.0, hi=1.0)  # long-run fraction of pings lost
    drop_burst_pings: float = _f(2.0, lo=1.0)  # mean length of a burst of drops
    multipath_prob: float = _f(0.06, lo=0.0, hi=1.0)
    multipath_mean_m: float = _f(40.0, lo=0.0)
    # with a maximum, multipath lengths are uniform in [min, max] instead of exponential
    multipath_min_m: float = _f(0.0, lo=0.0)
    multipath_max_m: float = _f(0.0, lo=0.0)
    corrupt_position_prob: float = _f(0.03, lo=0.0, hi=1.0)
    # gross corruptions of the reply's position: latitude off by 0.1 to 5 degrees, or
    # longitude read as 0 (what an independent simulator of the deck box produced)
    corrupt_gross_prob: float = _f(0.0, lo=0.0, hi=1.0)
    temperature_c: float = _f(10.0, lo=-2.0, hi=40.0)
    salinity_ppt: float = _f(0.2, lo=0.0, hi=45.0)
    modem_mps: float = _f(1500.0, gt=1300.0, hi=1700.0)
    turnaround_s: float = _f(0.0, lo=0.0)
    timeout_s: float = _f(8.0, gt=0.0)
    # spans without the boat's location line (its GPS or the shore link down): the
    # replies carry no position; their number, each lasting between min and max
    location_outages: int = _f(0, lo=0, hi=100)
    location_outage_min_s: float = _f(60.0, gt=0.0)
    location_outage_max_s: float = _f(300.0, gt=0.0)
    # fixed LBL transponders interrogated round robin, one per ping; empty: the boat's UDB
    transponders: list[Transponder] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class Scenario:
    name: str = "unnamed"
    description: str = ""
    start_utc: str = "2016-01-08T15:04:05Z"
    surface_altitude_m: float = _f(0.0, lo=-200.0, hi=5000.0)
    bench: bool = True  # part of make bench-accuracy
    vehicle: Vehicle = field(default_factory=Vehicle)
    current: Current = field(default_factory=Current)
    sensors: Sensors = field(default_factory=Sensors)
    boat: Boat = field(default_factory=Boat)
    acoustics: Acoustics = field(default_factory=Acoustics)
    config: dict[str, object] = field(default_factory=dict)


def scenario_dir() -> Path:
    return Path(str(resources.files("navd.hil") / "scenarios"))


def list_scenarios() -> list[str]:
    return sorted(p.stem for p in scenario_dir().glob("*.yaml"))


def load_scenario(name_or_path: str | Path) -> Scenario:
    p = Path(name_or_path)
    if not p.suffix:
        p = scenario_dir() / f"{name_or_path}.yaml"
        if not p.exists():
            raise ConfigError(
                f"no scenario named {str(name_or_path)!r}; there are: {', '.join(list_scenarios())}"
            )
    try:
        data = files.load_yaml(p)
    except files.FileRefused as exc:
        raise ConfigError(str(exc)) from None
    try:
        return scenario_from_dict(data)
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None


def scenario_from_dict(data: object) -> Scenario:
    """Validate a scenario mapping (as a YAML file holds it); ``config`` is the crew's."""
    if not isinstance(data, dict):
        raise ConfigError("expected a mapping")
    data = dict(data)
    cfg = data.pop("config", None) or {}
    sc = build(Scenario, data)
    if len(sc.sensors.compass_deviation_deg) not in (0, 5):
        raise ConfigError("sensors.compass_deviation_deg: expected A, B, C, D, E (or none)")
    if not isinstance(cfg, dict):
        raise ConfigError("config: expected a mapping")
    return Scenario(**{**{f: getattr(sc, f) for f in sc.__dataclass_fields__}, "config": cfg})
