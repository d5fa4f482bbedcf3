"""What navd says: the estimate, the range decision and health, defined once.

The filter builds these, the daemon logs and publishes them, ``navd replay`` writes
them and ``navd report`` reads them; every field has one name everywhere (documented
in docs/schema.md).  :func:`to_dict` is their serialised form: the fields in
declaration order, optional fields left out while they are None.  The JSON text is
made by :mod:`navd.formats.jsonlines` alone.

The one place a type name differs is the daemon's own log, which holds the measured
ranges too: there a range decision is written as ``decision`` (:data:`LOG_TYPE`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import MISSING, dataclass, field, fields
from operator import attrgetter
from typing import Any, TypeVar

from navd.formats.jsonlines import JsonObject

#: the version in every zenoh message (``schema``); it changes when a field changes meaning
SCHEMA_VERSION = 1

#: output types as the daemon's log writes them, where they would clash with a measurement
LOG_TYPE = {"range": "decision"}
#: and back
FROM_LOG_TYPE = {v: k for k, v in LOG_TYPE.items()}


def _optional() -> Any:
    return field(default=None, metadata={"optional": True})


@dataclass(frozen=True, slots=True)
class Estimate:
    """One filter step (10 Hz). Positions WGS-84 degrees, lengths metres, speeds m/s."""

    t: float  # the filter's time: monotonic seconds live, log seconds in replay
    lat: float
    lon: float
    current_n: float
    current_e: float
    std_n: float  # one-sigma position uncertainty north, east
    std_e: float
    cov_ne: float  # their covariance, m^2
    depth: float
    mode: str  # surface | surfacing | submerged
    integrity: str  # ok | degraded | lost
    integrity_reason: str | None = _optional()
    heading_bias_deg: float | None = _optional()  # default mode's extra states
    speed_scale: float | None = _optional()
    beacon_offset_n: float | None = _optional()
    beacon_offset_e: float | None = _optional()
    # default mode: the weight the ranges give to "the config's calibration priors are wrong"
    calibration_doubt: float | None = _optional()
    # default mode: true once those priors are refuted and the uncalibrated belief is followed
    calibration_refuted: bool | None = _optional()
    heading_deg: float = 0.0  # true heading and water speed the filter used
    speed_mps: float = 0.0
    dr_lat: float | None = _optional()  # dead reckoning since the last fix
    dr_lon: float | None = _optional()
    fix_lat: float | None = _optional()  # the virtual-LBL least-squares fix, while fresh
    fix_lon: float | None = _optional()
    fix_std_m: float | None = _optional()
    fix_age_s: float | None = _optional()
    dvl_lat: float | None = _optional()  # DVL dead reckoning and its predicted error
    dvl_lon: float | None = _optional()
    dvl_error_pred_m: float | None = _optional()
    dvl_time_to_limit_s: float | None = _optional()
    stale: list[str] | None = _optional()  # inputs older than navigation.stale_input_s
    smoothed: bool | None = _optional()  # written by the RTS smoother
    t_utc: str | None = _optional()  # the daemon adds the system clock's UTC
    type: str = "estimate"


@dataclass(frozen=True, slots=True)
class RangeDecision:
    """What the filter did with one range or travel time."""

    t: float  # the reply's arrival
    t_ping: float
    beacon: str
    beacon_lat: float | None = _optional()  # the beacon position used
    beacon_lon: float | None = _optional()
    beacon_depth: float | None = _optional()
    # the reply carried no position: the beacon was predicted, this long after its last
    beacon_predicted_s: float | None = _optional()
    range_m: float | None = _optional()  # the range with the water's sound speed
    accepted: bool = False
    residual_m: float | None = None  # None: the range never reached the gate
    gate_m: float | None = None
    reason: str = ""  # ok, gate, or why it never reached the gate
    # the residual squared over the variance the filter expected of it (None: the range
    # never reached a gate that knows that variance: thesis and vlbl modes)
    nis: float | None = _optional()
    type: str = "range"


@dataclass(frozen=True, slots=True)
class Advisory:
    """How well the recent ranges fix each horizontal direction, and what would help."""

    t: float
    verdict: str  # ok | weak_cross_range | no_ranges
    ranges: int  # accepted ranges in the window
    window_s: float
    bearing_spread_deg: float | None = _optional()  # of the lines of sight to the beacon
    info_ratio: float | None = _optional()  # worst / best direction's range information
    weak_axis_deg: float | None = _optional()  # the least fixed direction, from true north
    weak_std_m: float | None = _optional()  # how well ranges alone fix it (1 / sqrt(info))
    suggest_heading_deg: float | None = _optional()  # steer across the line of sight
    suggest_turn_deg: float | None = _optional()  # from the present heading, + to starboard
    type: str = "advisory"


@dataclass(slots=True)
class DeviceHealth:
    connected: bool
    last_rx_age_s: float | None
    rate_hz: float  # records a second over the last 5 s
    records: int
    bad_checksum: int
    bad_frame: int
    skipped_bytes: int
    reconnects: int
    opens: int
    read_errors: int
    write_errors: int
    last_error: str
    device_errors: int  # error answers from the device
    resets: int
    last_device_error: str
    info: dict[str, object]  # what the device said of itself: firmware, serial number, ...
    internal_errors: dict[str, int]
    # what the decoder skipped or could not use, by reason and sentence type
    decode_reasons: dict[str, int] = field(default_factory=dict)


@dataclass(slots=True)
class Health:
    """The daemon's state at 1 Hz: ``ok`` false with reasons in ``degraded``."""

    t: float
    mode: str
    integrity: str
    ok: bool
    degraded: list[str]
    estimates_per_s: float
    input_age_s: dict[str, float | None]
    last_range_accepted_age_s: float | None
    devices: dict[str, DeviceHealth]
    pings: dict[str, object]
    modem: dict[str, object]
    filter: dict[str, int]
    ticks: int
    tick_overruns: int
    tick_lateness_ms: dict[str, float | None]
    publish_latency_ms: dict[str, float | None]
    log: dict[str, object]
    zenoh: dict[str, object]
    temperature_c: float | None
    gps_utc: str | None
    esc: dict[str, float]
    # the checkpoint kept for a restart, and what this run resumed from (None: not kept)
    checkpoint: dict[str, object] | None = _optional()
    type: str = "health"


def _plan(cls: type) -> tuple[tuple[str, bool], ...]:
    return tuple((f.name, bool(f.metadata.get("optional"))) for f in fields(cls))


_PLANS = {cls: _plan(cls) for cls in (Estimate, RangeDecision, Advisory, DeviceHealth, Health)}
_KNOWN = {cls: frozenset(name for name, _ in plan) for cls, plan in _PLANS.items()}


class _FlatPlan:
    """How a record of flat fields is serialised: every value in one ``attrgetter`` call,
    then the optional ones that are None taken out (the filter writes one a tick)."""

    def __init__(self, cls: type[Estimate] | type[RangeDecision] | type[Advisory]) -> None:
        plan = [(n, o) for n, o in _PLANS[cls] if n != "type"]
        self.names = tuple(n for n, _ in plan)
        self.get = attrgetter(*self.names)
        self.optional = tuple(n for n, o in plan if o)

    def __call__(self, obj: Estimate | RangeDecision | Advisory) -> dict[str, object]:
        out: dict[str, object] = {"type": obj.type}
        out.update(zip(self.names, self.get(obj), strict=True))
        for name in self.optional:
            if out[name] is None:
                del out[name]
        return out

    def finite(self, obj: Estimate | RangeDecision | Advisory) -> bool:
        """Whether every number in it is finite (None, a string or a flag is not a number)."""
        # one sum is NaN or infinite exactly when one of its terms is (all are bounded)
        return math.isfinite(sum([v for v in self.get(obj) if type(v) is float]))


_FLAT = {cls: _FlatPlan(cls) for cls in (Estimate, RangeDecision, Advisory)}

#: what the navigator gives for a record or a tick, in time order
Output = Estimate | RangeDecision
#: what navd logs and publishes of its own
Published = Estimate | RangeDecision | Advisory | Health


def finite(obj: Estimate | RangeDecision | Advisory) -> bool:
    """Whether every number of an estimate, decision or advisory is finite."""
    return _FLAT[type(obj)].finite(obj)


def to_dict(obj: Estimate | RangeDecision | Advisory | Health | DeviceHealth) -> dict[str, object]:
    """The serialised form: ``type`` first, optional fields left out while None.

    A device's ``info`` is spread into its entry (``firmware``, ``serial_number``...).
    """
    if isinstance(obj, Estimate | RangeDecision | Advisory):
        return _FLAT[type(obj)](obj)
    out: dict[str, object] = {}
    if not isinstance(obj, DeviceHealth):
        out["type"] = obj.type
    for name, optional in _PLANS[type(obj)]:
        v = getattr(obj, name)
        if name == "type" or (optional and v is None):
            continue
        if name == "info":
            out.update(v)
        elif isinstance(v, DeviceHealth):
            out[name] = to_dict(v)
        elif name == "devices":
            out[name] = {k: to_dict(d) for k, d in v.items()}
        else:
            out[name] = v
    return out


def split_outputs(outputs: Iterable[Output]) -> tuple[list[Estimate], list[RangeDecision]]:
    """The estimates and the range decisions of a run, each in time order."""
    est: list[Estimate] = []
    dec: list[RangeDecision] = []
    for o in outputs:
        if isinstance(o, Estimate):
            est.append(o)
        else:
            dec.append(o)
    return est, dec


def output_of(row: JsonObject) -> Output | str | None:
    """A row of a replay output or a daemon log as an estimate or a range decision;
    None for any other row (a measurement, health, an advisory), or what is wrong with it.

    A decision is a ``range`` with ``accepted`` (a measured range never has it), or a
    daemon log's ``decision``.
    """
    kind = row.get("type")
    if kind == "estimate":
        cls: type[Estimate] | type[RangeDecision] = Estimate
        what = "an estimate"
    elif (kind == "range" and "accepted" in row) or FROM_LOG_TYPE.get(str(kind)) == "range":
        cls = RangeDecision
        what = "a range decision"
    else:
        return None
    for name, kinds in _NUMBERS[cls].items():
        v = row.get(name)
        if v is None and name in _REQUIRED[cls]:
            return f"{what} without {name}"
        if v is not None and (type(v) is bool or not isinstance(v, kinds)):
            return f"{what} whose {name} is not a number"
    try:
        if cls is RangeDecision:
            return from_dict(RangeDecision, {**row, "type": "range"})
        return from_dict(Estimate, row)
    except TypeError:
        missing = sorted(_REQUIRED[cls] - row.keys())
        return f"{what} without {', '.join(missing) or 'its fields'}"


def _numbers(cls: type) -> dict[str, tuple[type, ...]]:
    """The fields of ``cls`` that hold a number (an int is one where a float is asked)."""
    out: dict[str, tuple[type, ...]] = {}
    for f in fields(cls):
        ann = str(f.type).replace(" ", "")
        if ann in ("float", "float|None"):
            out[f.name] = (int, float)
        elif ann in ("int", "int|None"):
            out[f.name] = (int,)
    return out


_NUMBERS = {cls: _numbers(cls) for cls in (Estimate, RangeDecision)}
_REQUIRED = {
    cls: frozenset(f.name for f in fields(cls) if f.default is MISSING)
    for cls in (Estimate, RangeDecision)
}


T = TypeVar("T", Estimate, RangeDecision, Advisory)


def from_dict(cls: type[T], d: dict[str, Any]) -> T:
    """A published or logged record back into its dataclass.

    Fields this version does not know (added by a newer navd, or zenoh's ``schema``
    and ``seq``) are left out, so a reader keeps working as fields are added.
    """
    known = _KNOWN[cls]
    return cls(**{k: v for k, v in d.items() if k in known})
