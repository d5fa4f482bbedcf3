"""Measurement records: the typed, immutable values that flow from drivers and logs into the filter.

``t`` is always seconds on the record's own time base (mission seconds in a
measurement log, monotonic seconds in the daemon).  Angles are degrees and
positions WGS-84 degrees, as in the replay contract; the filter converts to SI
radians at its edge.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass, fields

#: How long after its first byte a measurement may still be completing.  A Benthos
#: range is stamped when its ``Range`` line arrives but is complete only with the
#: location line behind it (53 bytes: 55 ms at 9600 baud, 0.44 s at 1200); other
#: sensors' records arrive meanwhile.  Such a record is fused at its own time; one
#: later than this is out of order.
MAX_LATE_S = 2.0


@dataclass(frozen=True, slots=True)
class Heading:
    t: float
    deg: float  # clockwise from magnetic north


@dataclass(frozen=True, slots=True)
class Attitude:
    t: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float  # clockwise from magnetic north


@dataclass(frozen=True, slots=True)
class Rpm:
    t: float
    rpm: float


@dataclass(frozen=True, slots=True)
class Depth:
    t: float
    m: float  # positive down


@dataclass(frozen=True, slots=True)
class Pressure:
    t: float
    bar: float  # absolute


@dataclass(frozen=True, slots=True)
class Gps:
    t: float
    lat: float | None
    lon: float | None
    # ellipsoidal height: only when the receiver gave the geoid separation (NMEA) or
    # the height above the ellipsoid itself (gpsd's altHAE); never an MSL height
    alt: float | None
    fix: int  # 0 none, 1 GPS, 2 DGPS
    hdop: float | None = None
    # the receiver's GGA quality: 1 GPS, 2 DGPS, 3 PPS, 4 RTK fixed, 5 RTK float, 9 WAAS
    quality: int | None = None
    alt_msl: float | None = None  # height above mean sea level (the geoid), as received
    geoid_sep: float | None = None  # geoid above the ellipsoid, when the receiver said
    sats: int | None = None  # satellites used, when the receiver said


@dataclass(frozen=True, slots=True)
class Range:
    t: float  # reply arrival
    t_ping: float  # request departure
    m: float  # one-way range computed by the modem with its own sound speed
    beacon: str
    beacon_lat: float | None = None
    beacon_lon: float | None = None
    beacon_depth: float | None = None
    # the round trip the modem measured (its range is this times its sound speed over
    # two): when present the filter ranges from it with the water's sound speed
    twtt_s: float | None = None
    speed_mps: float | None = None  # the modem's relative speed: a diagnostic, not fused


@dataclass(frozen=True, slots=True)
class TravelTime:
    t: float
    t_ping: float
    twtt_s: float
    beacon: str
    beacon_lat: float | None = None
    beacon_lon: float | None = None
    beacon_depth: float | None = None


@dataclass(frozen=True, slots=True)
class Velocity:
    t: float
    u: float
    v: float
    w: float


@dataclass(frozen=True, slots=True)
class Reset:
    """The operator's ``cmd/reset``: forget the estimate, start again at the next GPS fix.

    Commands are records like measurements so that the daemon's log holds them in
    order and ``navd replay`` re-applies them: a replay reproduces the live run.
    """

    t: float


#: beacons navd keeps, configured and commanded: bounds what a command (or a log of
#: commands) can make it keep
MAX_BEACONS = 16
#: beacon names: short, printable, safe in a log line and a zenoh key
BEACON_NAME = re.compile(r"[A-Za-z0-9_.-]{1,32}")


@dataclass(frozen=True, slots=True)
class SetBeacon:
    """The operator's ``cmd/beacon``: where a beacon is, for replies that carry no position."""

    t: float
    beacon: str
    lat: float
    lon: float
    depth: float = 0.0


@dataclass(frozen=True, slots=True)
class Clock:
    """The GPS receiver's UTC at ``t``, from the time and date of a fix it says is valid
    (RMC status A, gpsd's TPV with a fix): the time the crew's tidal prediction is read in
    (navd/filter/tide.py), where the computer's own clock may be hours off (a board with no
    real-time clock, at sea without a network)."""

    t: float
    utc_s: float  # seconds since the Unix epoch


@dataclass(frozen=True, slots=True)
class Resume:
    """navd started again and resumed the navigation state of its checkpoint.

    The daemon writes it into its log as it applies it (``cmd_resume``), so that a
    replay of the log resumes the same state and gives the estimates given live.
    ``x`` and ``P`` are the filter's state vector and covariance (row by row) as
    ``mode``'s filter holds them; ``age_s`` how old the checkpoint was; the position
    covariance has been grown for it already.
    """

    t: float
    mode: str
    x: tuple[float, ...]
    P: tuple[float, ...]
    age_s: float
    surface_bar: float | None = None  # the depth gauge's zero
    surface_alt: float | None = None  # the water's ellipsoidal height
    depth_m: float | None = None  # the depth then: the vehicle is submerged until it says not
    # the ranges' common scale error as learnt, and its variance (navd/filter/range_biases.py);
    # ``P`` holds what that variance did to the position already
    range_scale: float | None = None
    range_scale_var: float | None = None
    # the tracked beacon's outage under way (navd/filter/common.py, ``Held.outage``): its
    # report's time, its start, the beacon offset's mean and covariance then, the
    # prediction's largest std; ``P`` holds its error already
    beacon_outage: tuple[float, ...] | None = None
    # how often replies read long past the gate (navd/filter/common.py,
    # ``Held.long_refused``): the forgotten counts of such refusals and of ranges
    long_refused: tuple[float, float] | None = None
    # the range noise learnt beyond the config's (navd/filter/common.py,
    # ``Held.range_noise``): the forgotten sums over its pairs of residuals
    range_noise: tuple[float, ...] | None = None


@dataclass(frozen=True, slots=True)
class Tick:
    """A filter step the daemon took at ``t``, read back from its log (an ``estimate`` line).

    Live, the 10 Hz tick runs between serial records; a range completed after a tick
    is fused after it.  Replay steps the filter at the same places in the record stream,
    so it reproduces the live estimates exactly.  Not a measurement: never written.
    """

    t: float


Record = (
    Tick
    | Heading
    | Attitude
    | Rpm
    | Depth
    | Pressure
    | Gps
    | Range
    | TravelTime
    | Velocity
    | Reset
    | SetBeacon
    | Resume
    | Clock
)

#: measurement-log ``type`` name of each record class
TYPE_NAMES: dict[type, str] = {
    Heading: "heading",
    Attitude: "attitude",
    Rpm: "rpm",
    Depth: "depth",
    Pressure: "pressure",
    Gps: "gps",
    Range: "range",
    TravelTime: "travel_time",
    Velocity: "velocity",
    Reset: "cmd_reset",
    SetBeacon: "cmd_beacon",
    Resume: "cmd_resume",
    Clock: "clock",
}


#: What each measured quantity can physically be: the decoders, the log reader and the
#: navigator all refuse a record with a value outside (or not finite), so the live
#: daemon and a replay of its log agree.  Keyed by (record type, field).
BOUNDS: dict[tuple[type, str], tuple[float, float]] = {
    (Heading, "deg"): (-360.0, 360.0),
    (Attitude, "roll_deg"): (-360.0, 360.0),
    (Attitude, "pitch_deg"): (-360.0, 360.0),
    (Attitude, "yaw_deg"): (-360.0, 360.0),
    (Rpm, "rpm"): (-100_000.0, 100_000.0),
    (Depth, "m"): (-100.0, 11_000.0),
    (Pressure, "bar"): (0.0, 2000.0),
    (Gps, "lat"): (-90.0, 90.0),
    (Gps, "lon"): (-180.0, 180.0),
    (Gps, "alt"): (-1000.0, 10_000.0),
    (Gps, "hdop"): (0.0, 1000.0),
    (Gps, "quality"): (0, 9),
    (Gps, "alt_msl"): (-1000.0, 10_000.0),
    (Gps, "geoid_sep"): (-150.0, 150.0),
    (Gps, "sats"): (0, 999),
    (Range, "m"): (0.0, 1e6),
    (Range, "twtt_s"): (0.0, 1e3),
    (Range, "speed_mps"): (-100.0, 100.0),
    (TravelTime, "twtt_s"): (0.0, 1e3),
    (Range, "beacon_lat"): (-90.0, 90.0),
    (Range, "beacon_lon"): (-180.0, 180.0),
    (Range, "beacon_depth"): (-100.0, 11_000.0),
    (TravelTime, "beacon_lat"): (-90.0, 90.0),
    (TravelTime, "beacon_lon"): (-180.0, 180.0),
    (TravelTime, "beacon_depth"): (-100.0, 11_000.0),
    (Velocity, "u"): (-50.0, 50.0),
    (Velocity, "v"): (-50.0, 50.0),
    (Velocity, "w"): (-50.0, 50.0),
    (SetBeacon, "lat"): (-90.0, 90.0),
    (SetBeacon, "lon"): (-180.0, 180.0),
    (SetBeacon, "depth"): (0.0, 11_000.0),
    # from 2010 to 2200: a receiver past a GPS week rollover its firmware predates
    # reports a date 1024 weeks (19.6 years) early, about 2007 in these years, and is
    # refused; the logs and captures of the years since stay readable
    (Clock, "utc_s"): (1.2623e9, 7.26e9),
    (Resume, "age_s"): (0.0, 1e6),
    (Resume, "surface_bar"): (0.0, 2000.0),
    (Resume, "surface_alt"): (-1000.0, 10_000.0),
    (Resume, "depth_m"): (-100.0, 11_000.0),
    (Resume, "range_scale"): (-0.5, 0.5),
    (Resume, "range_scale_var"): (0.0, 1.0),
}
#: a time stamp beyond about 30 years of seconds is corrupt, not a mission
MAX_ABS_T = 1e9


def _limits(cls: type) -> tuple[tuple[str, float, float], ...]:
    """Each field of ``cls`` with its bounds (worked out once per record type); a field
    without bounds gets the largest finite floats, so one comparison refuses NaN and
    infinities too."""
    out = []
    for f in fields(cls):
        if f.name in ("t", "t_ping"):
            lo, hi = -MAX_ABS_T, MAX_ABS_T
        else:
            lo, hi = BOUNDS.get((cls, f.name), (-sys.float_info.max, sys.float_info.max))
        out.append((f.name, lo, hi))
    return tuple(out)


_LIMITS: dict[type, tuple[tuple[str, float, float], ...]] = {}


def implausible(rec: object) -> str | None:
    """Why ``rec`` cannot be a measurement (a field out of its bounds), or None."""
    cls = type(rec)
    limits = _LIMITS.get(cls)
    if limits is None:
        limits = _LIMITS[cls] = _limits(cls)
    for name, lo, hi in limits:
        v = getattr(rec, name)
        tv = type(v)
        if tv is not float and tv is not int:  # the common case first: replay reads 1e5/s
            if v is None or tv is str:
                continue
            if tv is tuple:  # a state vector: finite numbers, of bounded size
                if len(v) > 256 or not all(
                    type(a) in (float, int) and math.isfinite(a) and abs(a) < 1e12 for a in v
                ):
                    return f"field '{name}' is not a list of finite numbers"
                continue
            if isinstance(v, bool) or not isinstance(v, int | float):
                return f"field '{name}' is not a finite number"
        if lo <= v <= hi:
            continue
        if isinstance(v, float) and not math.isfinite(v):
            return f"field '{name}' is not a finite number"
        shown = f"{v:.6g}" if isinstance(v, float) or abs(v) < 10**15 else "a huge integer"
        return f"field '{name}'={shown} outside [{lo:g}, {hi:g}]"
    if isinstance(rec, Range | TravelTime) and rec.t_ping > rec.t:
        return "t_ping is after t"
    return None
