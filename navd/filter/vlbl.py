"""Virtual long baseline (LaPointe 2006, seed 001) and the fixed-array fix it generalises.

Each range is kept with where dead reckoning said the vehicle was when it arrived.
To fix the present position, every kept range's beacon is moved by the
dead-reckoned displacement since that range (eq. 3.1-3.3: the virtual transponder
is the real one translated by the vehicle's motion), and the ranges to these
virtual transponders are solved as one LBL fix with the iterative least squares
of seed 004 (navd/filter/lsfix.py).  With one transponder the net is built in time; with
several fixed transponders interrogated round robin it is the ordinary LBL fix
with the vehicle's motion between pings taken out.  Moving beacons (a boat) work
the same way, since each range keeps the beacon position it was measured to.

The seed's outlier tests: a range whose residual exceeds ``outlier_sigma`` times
its expected error (range noise plus the dead-reckoning drift accumulated since
it) is dropped and the net solved again, once per range.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from navd import geodesy
from navd.filter.lsfix import Fix, RangeTo, least_squares_fix


@dataclass(frozen=True, slots=True)
class NetRange:
    t: float
    lat: float  # beacon, radians
    lon: float
    hd: float
    range_m: float
    std_m: float
    rel_n: float  # dead-reckoned displacement since an arbitrary origin, metres
    rel_e: float


class VirtualNet:
    def __init__(
        self,
        window_s: float = 120.0,
        max_ranges: int = 8,
        drift_mps: float = 0.1,
        outlier_sigma: float = 3.0,
    ) -> None:
        self.window_s = window_s
        self.drift = drift_mps  # how fast dead reckoning drifts (current, compass, speed map)
        self.outlier_sigma = outlier_sigma
        self.ranges: deque[NetRange] = deque(maxlen=max_ranges)
        self.fix: Fix | None = None
        self.t_fix: float | None = None
        self.outliers = 0
        self.fixes = 0
        # where the vehicle is relative to where it started, by dead reckoning: the net
        # moves old ranges along it, and needs no absolute position
        self.rel_n = 0.0
        self.rel_e = 0.0

    def move(self, distance_m: float, heading: float) -> None:
        """The vehicle went ``distance_m`` along ``heading`` (radians from true north)."""
        self.rel_n += distance_m * math.cos(heading)
        self.rel_e += distance_m * math.sin(heading)

    def clear(self) -> None:
        self.ranges.clear()

    def add(self, r: NetRange, vehicle_hd: float, guess: tuple[float, float] | None) -> Fix | None:
        self.ranges.append(r)
        while self.ranges and r.t - self.ranges[0].t > self.window_s:
            self.ranges.popleft()
        fix = self._solve(r, vehicle_hd, guess)
        if fix is not None:
            self.fix, self.t_fix = fix, r.t
            self.fixes += 1
        return fix

    def _virtual(self, now: NetRange, keep: list[NetRange]) -> list[RangeTo]:
        out = []
        for q in keep:
            dn, de = now.rel_n - q.rel_n, now.rel_e - q.rel_e
            lat, lon = geodesy.offset_position(q.lat, q.lon, dn, de, q.hd)
            std = math.hypot(q.std_m, self.drift * (now.t - q.t))
            out.append(RangeTo(lat, lon, q.hd, q.range_m, std))
        return out

    def _solve(self, now: NetRange, hd: float, guess: tuple[float, float] | None) -> Fix | None:
        keep = list(self.ranges)
        for _ in range(len(keep)):
            if len(keep) < 3:
                return None
            net = self._virtual(now, keep)
            fix = least_squares_fix(net, hd, guess)
            if fix is None:
                return None
            worst, worst_z = None, 0.0
            for q, v in zip(keep, net, strict=True):
                pred = geodesy.ecef_distance(fix.lat, fix.lon, hd, v.lat, v.lon, v.hd)
                z = abs(v.range_m - pred) / v.std_m
                if z > worst_z:
                    worst, worst_z = q, z
            if worst_z <= self.outlier_sigma:
                return fix
            keep.remove(worst)  # type: ignore[arg-type]
            self.outliers += 1
        return None
