"""Where the beacon was: the position carried in each reply, checked, or the configured one."""

from __future__ import annotations

import math
from dataclasses import dataclass

from navd import geodesy
from navd.config import Beacon, GateConfig

# GPS on the boat wanders by about this much between fixes (seed 000: 10 m 2D RMS).
_POSITION_SLACK_M = 30.0


@dataclass(frozen=True, slots=True)
class BeaconFix:
    lat: float  # radians
    lon: float
    depth: float
    turnaround_s: float
    position_std_m: float
    position_corr_s: float


class BeaconResolver:
    """Resolves and sanity-checks beacon positions, per beacon name.

    A reply position is used field by field where present, the configured
    ``beacons.<name>`` where not.  A position that would need the beacon to move
    faster than ``gate.max_beacon_speed_mps`` since the last good one is treated as
    corrupted, unless the next reply confirms it (the boat really did move, or the
    first position we saw was the corrupt one).
    """

    def __init__(self, beacons: dict[str, Beacon], gate: GateConfig) -> None:
        self.beacons = dict(beacons)  # commands add to it: the config's own is not changed
        self.max_speed = gate.max_beacon_speed_mps
        self._last: dict[str, tuple[float, float, float]] = {}
        self._candidate: dict[str, tuple[float, float, float]] = {}

    def _moved_too_far(
        self, a: tuple[float, float, float], t: float, lat: float, lon: float
    ) -> bool:
        ta, lat_a, lon_a = a
        e, n, _ = geodesy.enu_offset(lat_a, lon_a, 0.0, lat, lon, 0.0)
        return math.hypot(e, n) > _POSITION_SLACK_M + self.max_speed * abs(t - ta)

    def resolve(
        self,
        t: float,
        name: str,
        lat_deg: float | None,
        lon_deg: float | None,
        depth: float | None,
    ) -> tuple[BeaconFix | None, str]:
        cfg = self.beacons.get(name)
        lat = lat_deg if lat_deg is not None else (cfg.lat if cfg else None)
        lon = lon_deg if lon_deg is not None else (cfg.lon if cfg else None)
        if depth is None:
            depth = cfg.depth if cfg else 0.0
        spec = cfg or Beacon()
        if lat is None or lon is None:
            return None, "no_beacon_position"
        lat_r, lon_r = math.radians(lat), math.radians(lon)
        carried = lat_deg is not None or lon_deg is not None
        if carried:
            last = self._last.get(name)
            if last is not None and self._moved_too_far(last, t, lat_r, lon_r):
                cand = self._candidate.get(name)
                self._candidate[name] = (t, lat_r, lon_r)
                if cand is None or self._moved_too_far(cand, t, lat_r, lon_r):
                    return None, "beacon_jump"
            self._candidate.pop(name, None)
            self._last[name] = (t, lat_r, lon_r)
        return (
            BeaconFix(
                lat_r, lon_r, depth, spec.turnaround_s, spec.position_std_m, spec.position_corr_s
            ),
            "ok",
        )
