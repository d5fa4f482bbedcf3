"""A mission as the post-mission formats write it: the navigator's outputs over one log,
with the log's GPS fixes, records and health (``navd.analysis.export`` builds it)."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from navd.formats.jsonlines import JsonObject
from navd.records import Gps, Record
from navd.schema import Estimate, RangeDecision


@dataclass(frozen=True, slots=True)
class Surfacing:
    """The last submerged estimate, the first GPS fix after it, and how far apart."""

    t: float
    lat: float
    lon: float
    fix_lat: float
    fix_lon: float
    error_m: float
    after_s: float  # from the last submerged estimate to the fix


@dataclass(slots=True)
class Mission:
    estimates: list[Estimate]
    decisions: list[RangeDecision]
    fixes: list[Gps]
    records: list[Record]
    epoch_s: float  # Unix time of t = 0 (the log's time base)
    smoothed: list[Estimate] = field(default_factory=list)
    # the daemon's health lines as logged (a measurement log has none)
    health: list[JsonObject] = field(default_factory=list)
    surfacings: list[Surfacing] = field(default_factory=list)  # one per dive

    def utc(self, t: float) -> dt.datetime:
        return dt.datetime.fromtimestamp(self.epoch_s + t, dt.UTC)
