"""Observability advisory: how well the recent ranges fix each horizontal direction.

A range fixes the vehicle only along the line of sight to the beacon.  Seeds 000
and 001 both show a track run radially to a single beacon leaving the cross-range
direction unobserved, while the estimate drifts across it.  Over the last
``WINDOW_S`` seconds each accepted range adds ``u uᵀ / σ²`` (``u`` the horizontal
unit vector towards the beacon, ``σ`` the range noise) to the range information
matrix; its eigenvalues say how well ranges alone constrain the best and the worst
direction.  When the worst is below ``WEAK_RATIO`` of the best (bearings within
about ±18°) the verdict is ``weak_cross_range``, and the advice is to steer across
the line of sight, along the weak axis: the heading of the two that needs the
smaller turn.  It advises; it never steers.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

from navd import geodesy
from navd.filter.common import principal_axes
from navd.schema import Advisory, Estimate, RangeDecision

WINDOW_S = 300.0  # the last five minutes of ranges
WEAK_RATIO = 0.1  # smallest / largest information: tan² of a ±18° bearing spread
MIN_RANGES = 3  # fewer cannot show a spread of bearings


def _wrap180(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


class Observability:
    def __init__(self, window_s: float = WINDOW_S) -> None:
        self.window_s = window_s
        # (t, u_n, u_e, 1/σ²): one accepted range each
        self._los: deque[tuple[float, float, float, float]] = deque()

    def clear(self) -> None:
        self._los.clear()

    def add(
        self, t: float, lat: float, lon: float, beacon_lat: float, beacon_lon: float, std_m: float
    ) -> None:
        """An accepted range; positions in degrees (vehicle, beacon), ``std_m`` its noise."""
        e, n, _ = geodesy.enu_offset(
            math.radians(lat), math.radians(lon), 0.0,
            math.radians(beacon_lat), math.radians(beacon_lon), 0.0,
        )  # fmt: skip
        d = math.hypot(n, e)
        if not (d > 1e-3 and math.isfinite(d) and std_m > 0.0):
            return  # straight above the beacon: no horizontal line of sight
        self._los.append((t, n / d, e / d, 1.0 / (std_m * std_m)))

    def assess(self, t: float, heading_deg: float | None) -> Advisory:
        while self._los and t - self._los[0][0] > self.window_s:
            self._los.popleft()
        n = len(self._los)
        if n == 0:
            return Advisory(t, "no_ranges", 0, self.window_s)
        inn = sum(w * un * un for _, un, _, w in self._los)
        iee = sum(w * ue * ue for _, _, ue, w in self._los)
        ine = sum(w * un * ue for _, un, ue, w in self._los)
        big, small, strong = principal_axes(inn, iee, ine)
        small = max(small, 0.0)
        weak = (math.degrees(strong) + 90.0) % 180.0  # the least informed axis, from north
        bearings = [math.degrees(math.atan2(ue, un)) for _, un, ue, _ in self._los]
        ref = bearings[-1]
        offsets = [_wrap180(b - ref) for b in bearings]
        spread = max(offsets) - min(offsets)
        ratio = small / big if big > 0 else 0.0
        verdict = "weak_cross_range" if n < MIN_RANGES or ratio < WEAK_RATIO else "ok"
        adv = Advisory(
            t,
            verdict,
            n,
            self.window_s,
            bearing_spread_deg=round(spread, 2),
            info_ratio=round(ratio, 4),
            weak_axis_deg=round(weak, 2),
            weak_std_m=round(1.0 / math.sqrt(small), 2) if small > 0 else None,
        )
        if verdict != "ok" and heading_deg is not None and math.isfinite(heading_deg):
            turn_a = _wrap180(weak - heading_deg)
            turn_b = _wrap180(weak + 180.0 - heading_deg)
            turn = turn_a if abs(turn_a) <= abs(turn_b) else turn_b
            adv = replace(
                adv,
                suggest_turn_deg=round(turn, 1),
                suggest_heading_deg=round((heading_deg + turn) % 360.0, 1),
            )
        return adv


def replayed(
    estimates: list[Estimate],
    decisions: list[RangeDecision],
    range_std_m: float,
    every_s: float = 1.0,
) -> list[Advisory]:
    """The advisories a daemon would have published, from a mission's outputs (the
    accepted ranges placed at the estimate of their time), one every ``every_s``."""
    obs = Observability()
    accepted = [
        (d.t, d.beacon_lat, d.beacon_lon)
        for d in decisions
        if d.accepted and d.beacon_lat is not None and d.beacon_lon is not None
    ]
    out: list[Advisory] = []
    i = 0
    t_next = -math.inf
    for e in estimates:
        while i < len(accepted) and accepted[i][0] <= e.t:
            t, lat, lon = accepted[i]
            obs.add(t, e.lat, e.lon, lat, lon, range_std_m)
            i += 1
        if e.t >= t_next:
            out.append(obs.assess(e.t, e.heading_deg))
            t_next = e.t + every_s
    return out
