"""Where the beacon was: the position carried in each reply, checked, or the configured one.

When the boat's location line is down (its GPS, or the shore link that forwards it),
replies come without a position.  The beacon is then predicted from the positions it
reported over the last ``_FIT_S`` seconds, at the velocity they show, with an
uncertainty that grows with the time since the last one (the velocity's own error,
and a boat that changes speed or course), for at most ``beacons.<name>.predict_max_s``,
and only a boat whose reports lie on a straight line (one that holds a course).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from navd import geodesy
from navd.settings import Beacon, GateConfig

# GPS on the boat wanders by about this much between fixes (seed 000: 10 m 2D RMS).
_POSITION_SLACK_M = 30.0
# reported positions the prediction is fitted to (and how many it needs), and how much
# a boat's velocity wanders while it holds a course (white acceleration, m/s^2)
_FIT_S = 300.0
_FIT_MIN = 3
_BOAT_ACCEL_MPS2 = 0.005
_MISFIT_SIGMAS = 2.0  # reports further than this from the fitted line: not predicted


@dataclass(frozen=True, slots=True)
class BeaconFix:
    lat: float  # radians
    lon: float
    depth: float
    turnaround_s: float
    position_std_m: float
    position_corr_s: float
    predicted_s: float = 0.0  # > 0: predicted this long after the last reported position
    predicted_std_m: float = 0.0  # the prediction's own error, beside position_std_m
    predicted_from: float = math.nan  # the time of the report it was extrapolated from


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
        self._reported: dict[str, deque[tuple[float, float, float]]] = {}

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
            return self._predict(t, name, depth, spec)
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
            if lat_deg is not None and lon_deg is not None:
                seen = self._reported.setdefault(name, deque())
                seen.append((t, lat_r, lon_r))
                while seen and seen[0][0] < t - _FIT_S:
                    seen.popleft()
        # a configured position is a surveyed one: its error is the same for every reply
        corr_s = spec.position_corr_s if carried else math.inf
        return BeaconFix(lat_r, lon_r, depth, spec.turnaround_s, spec.position_std_m, corr_s), "ok"

    def _predict(
        self, t: float, name: str, depth: float, spec: Beacon
    ) -> tuple[BeaconFix | None, str]:
        """Where the beacon is now, from the velocity its recent reports show."""
        seen = self._reported.get(name)
        if not seen or len(seen) < _FIT_MIN:
            return None, "no_beacon_position"
        t_last, lat0, lon0 = seen[-1]
        age = t - t_last
        if not 0.0 <= age <= spec.predict_max_s:
            return None, "no_beacon_position"
        # least-squares velocity, in metres from the last report
        ts, ns, es = [], [], []
        for ti, la, lo in seen:
            e, n, _ = geodesy.enu_offset(lat0, lon0, 0.0, la, lo, 0.0)
            ts.append(ti - t_last)
            ns.append(n)
            es.append(e)
        k = len(ts)
        span = ts[-1] - ts[0]
        vn, ve = _slope(ts, ns), _slope(ts, es)
        if vn is None or ve is None or span <= 0.0:
            return None, "no_beacon_position"
        tm = sum(ts) / k
        nm, em = sum(ns) / k, sum(es) / k
        if math.hypot(vn, ve) > self.max_speed:
            return None, "no_beacon_position"
        # A boat that holds a course fits a straight line to within its GPS error; one
        # that wanders (holding station, turning) does not, and its velocity says
        # nothing of where it is going: such a boat is not predicted.
        misfit2 = sum(
            (n - nm - vn * (x - tm)) ** 2 + (e - em - ve * (x - tm)) ** 2
            for x, n, e in zip(ts, ns, es, strict=True)
        ) / (2 * k)
        if misfit2 > (_MISFIT_SIGMAS * max(spec.position_std_m, 1.0)) ** 2:
            return None, "no_beacon_position"
        # the fitted line through the mean, carried to now
        dn = nm + vn * (age - tm)
        de = em + ve * (age - tm)
        lat, lon = geodesy.offset_position(lat0, lon0, dn, de, 0.0)
        # The reports' errors are correlated over minutes, so the velocity is known
        # about as well as from two independent positions the fit's span apart.
        v_std = math.sqrt(2.0) * spec.position_std_m / span
        # what the line does not explain of the reports grows as it is carried on, and so
        # does the difference between the velocities of the window's two halves (a boat
        # whose course wanders has a velocity of the moment that its average is not)
        unexplained = max(0.0, misfit2 - spec.position_std_m**2) * (1.0 + age / span) ** 2
        dv2 = _half_velocity_change2(ts, ns, es, tm)
        var = (v_std * age) ** 2 + _BOAT_ACCEL_MPS2**2 * age**3 / 3.0 + unexplained
        var += dv2 * age * age
        return (
            BeaconFix(
                lat,
                lon,
                depth,
                spec.turnaround_s,
                spec.position_std_m,
                spec.position_corr_s,
                predicted_s=max(age, 1e-3),
                predicted_std_m=math.sqrt(var),
                predicted_from=t_last,
            ),
            "ok",
        )


def _slope(ts: list[float], ys: list[float]) -> float | None:
    if len(ts) < 2:
        return None
    tm = sum(ts) / len(ts)
    stt = sum((x - tm) ** 2 for x in ts)
    if stt <= 0.0:
        return None
    ym = sum(ys) / len(ys)
    return sum((x - tm) * (y - ym) for x, y in zip(ts, ys, strict=True)) / stt


def _half_velocity_change2(
    ts: list[float], ns: list[float], es: list[float], t_mid: float
) -> float:
    """Squared change between the velocities fitted to the earlier and later half."""
    early = [i for i, x in enumerate(ts) if x <= t_mid]
    late = [i for i, x in enumerate(ts) if x > t_mid]
    vs = []
    for idx in (early, late):
        vn = _slope([ts[i] for i in idx], [ns[i] for i in idx])
        ve = _slope([ts[i] for i in idx], [es[i] for i in idx])
        if vn is None or ve is None:
            return 0.0
        vs.append((vn, ve))
    (a_n, a_e), (b_n, b_e) = vs
    return (a_n - b_n) ** 2 + (a_e - b_e) ** 2
