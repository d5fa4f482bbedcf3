"""Measurement records: the typed, immutable values that flow from drivers and logs into the filter.

``t`` is always seconds on the record's own time base (mission seconds in a
measurement log, monotonic seconds in the daemon).  Angles are degrees and
positions WGS-84 degrees, as in the replay contract; the filter converts to SI
radians at its edge.
"""

from __future__ import annotations

from dataclasses import dataclass


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
    alt: float | None  # ellipsoidal height
    fix: int  # 0 none, 1 GPS, 2 DGPS
    hdop: float | None = None


@dataclass(frozen=True, slots=True)
class Range:
    t: float  # reply arrival
    t_ping: float  # request departure
    m: float  # one-way range computed by the modem with its own sound speed
    beacon: str
    beacon_lat: float | None = None
    beacon_lon: float | None = None
    beacon_depth: float | None = None


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


@dataclass(frozen=True, slots=True)
class SetBeacon:
    """The operator's ``cmd/beacon``: where a beacon is, for replies that carry no position."""

    t: float
    beacon: str
    lat: float
    lon: float
    depth: float = 0.0


Record = (
    Heading
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
}
