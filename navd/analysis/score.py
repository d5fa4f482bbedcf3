"""Scoring a mission: against the simulator's truth, or against GPS after surfacing.

Errors are measured on GeographicLib's ellipsoid, independent of navd's geodesy.
Only the submerged part of the mission is scored: at the surface every mode is
pinned to GPS.  The surfacing error is the error of the last submerged estimate:
against the truth at that time where the truth is known (:func:`score`), else
against the first GPS fix after it (``navd/analysis/surfacing.py``, what a field
mission has).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from geographiclib.geodesic import Geodesic

from navd.formats.truth import TruthSample
from navd.schema import Output, RangeDecision, split_outputs

_GEOD = Geodesic.WGS84
CHI2_2DOF_95 = 5.991  # 95 % quantile of chi-square with 2 degrees of freedom
CHI2_2DOF_99 = 9.210
_SUBMERGED_DEPTH_M = 0.3
REACQUIRED_S = 900.0  # how long after a re-acquisition its fit is judged on its own


@dataclass(frozen=True, slots=True)
class Score:
    rms_m: float
    p95_m: float
    surfacing_m: float  # error of the last submerged estimate
    inside95: float  # fraction of submerged time the truth lies in the 95 % ellipse
    current_rms_mps: float
    dr_rms_m: float
    dr_surfacing_m: float
    accepted: int
    rejected: int
    reacquisitions: int
    fix_rms_m: float = math.nan  # the virtual-LBL / LBL least-squares fix, when published
    fix_coverage: float = 0.0  # fraction of submerged time with a fix published
    # the most replies, over the mission's re-acquisitions, from the first gate rejection of
    # the streak to the next accepted range ("re-acquires within a few pings")
    reacquire_replies_max: float = math.nan
    # while integrity said ok: the fraction of that time the truth lies in the 99 % ellipse,
    # and the fraction of submerged time it said ok
    ok_inside99: float = math.nan
    ok_fraction: float = math.nan
    # in the quarter of an hour after each re-acquisition, when a filter has just put
    # a fit of a few ranges in place of what it knew: the fraction of that time the
    # truth lies in the 95 % ellipse, and the estimates that time holds
    reacquired_inside95: float = math.nan
    reacquired_estimates: int = 0
    # the error's squared Mahalanobis distance in its published ellipse over the submerged
    # time, per axis (the normalised estimation error squared: 1 for an ellipse the size
    # of the error, below it wider)
    nees: float = math.nan
    # the last submerged estimate: its error's squared Mahalanobis distance in its own
    # ellipse, and what integrity said of it (a large error the estimate knew of is not
    # the same as one it was sure it did not have)
    surfacing_d2: float = math.nan
    surfacing_integrity: str = ""


def replies_to_reacquire(ranges: list[RangeDecision]) -> list[int]:
    """Per re-acquisition: replies from the start of its rejection streak to the next accept."""
    out: list[int] = []
    start: int | None = None  # first gate rejection since the last accepted range
    reacquired = False
    for i, r in enumerate(ranges):
        if r.accepted:
            if reacquired and start is not None:
                out.append(i - start + 1)
            start, reacquired = None, False
        elif r.reason.startswith("gate"):
            start = i if start is None else start
            reacquired = reacquired or r.reason == "gate_reacquire"
    return out


_A, _E2 = _GEOD.a, _GEOD.f * (2.0 - _GEOD.f)
#: up to here the error's components come from the ellipsoid's radii, beyond from Inverse
_SHORT_M = 1000.0


def _ne_error(lat: float, lon: float, lat_t: float, lon_t: float) -> tuple[float, float]:
    """North and east of (lat, lon) from the truth (lat_t, lon_t), in metres.

    Errors under a kilometre, nearly all of them, are the latitude and longitude
    differences times the meridian and prime-vertical radii at the middle latitude
    (Rapp 1991, Geometric Geodesy I, 3.4): their length is the geodesic's within 2e-4 m
    up to 84 degrees of latitude (tests/test_score.py), without the inverse geodesic that
    was most of a Monte Carlo mission's time.  Their direction is the middle latitude's
    north, which turns from the truth's by up to d tan(lat) / 2N (the meridians'
    convergence over half the error): 8e-5 rad for 1 km at 45 degrees, 7e-4 rad at 84.
    """
    dlon = math.radians((lon - lon_t + 180.0) % 360.0 - 180.0)
    dlat = math.radians(lat - lat_t)
    phi = math.radians(0.5 * (lat + lat_t))
    w = math.sqrt(1.0 - _E2 * math.sin(phi) ** 2)
    n_rad = _A / w
    dn, de = dlat * n_rad * (1.0 - _E2) / (w * w), dlon * n_rad * math.cos(phi)
    if dn * dn + de * de < _SHORT_M * _SHORT_M:
        return dn, de
    g = _GEOD.Inverse(lat_t, lon_t, lat, lon)
    az = math.radians(g["azi1"])
    return g["s12"] * math.cos(az), g["s12"] * math.sin(az)


def _mahalanobis2(dn: float, de: float, var_n: float, var_e: float, cov: float) -> float:
    """dn, de against the 2x2 covariance (inf where it is not positive definite)."""
    det = var_n * var_e - cov * cov
    if not (det > 0.0 and var_n > 0.0):
        return math.inf
    return (dn * dn * var_e - 2.0 * dn * de * cov + de * de * var_n) / det


#: truth samples further apart than this are not interpolated between (a gap in the truth)
_TRUTH_MAX_STEP_S = 1.0


class TruthAt:
    """The truth at any time within its samples: linear between the two around it.

    Estimates are on the filter's ticks, truth on the simulator's steps; live, the
    daemon's ticks fall between them (a monotonic clock against mission time), so
    matching by equal time finds nothing.  Heading and speed are the earlier
    sample's (a heading does not interpolate across north)."""

    def __init__(self, truth: Sequence[TruthSample]) -> None:
        self.samples = sorted(truth, key=lambda s: s.t)
        self.ts = [s.t for s in self.samples]

    def __call__(self, t: float) -> TruthSample | None:
        i = bisect.bisect_left(self.ts, t)
        if i < len(self.ts) and abs(self.ts[i] - t) < 1e-6:
            return self.samples[i]
        if i == 0 or i == len(self.ts):
            return None
        a, b = self.samples[i - 1], self.samples[i]
        span = b.t - a.t
        if span > _TRUTH_MAX_STEP_S:
            return None
        w = (t - a.t) / span
        return TruthSample(
            t,
            a.lat + w * (b.lat - a.lat),
            a.lon + w * (b.lon - a.lon),
            a.depth + w * (b.depth - a.depth),
            a.heading_deg,
            a.speed_mps,
            a.current_n + w * (b.current_n - a.current_n),
            a.current_e + w * (b.current_e - a.current_e),
            a.boat_lat + w * (b.boat_lat - a.boat_lat),
            a.boat_lon + w * (b.boat_lon - a.boat_lon),
        )


def position_rms(
    points: Iterable[tuple[float, float, float]], truth: Sequence[TruthSample]
) -> float:
    """RMS horizontal error (m) of ``(t, lat, lon)`` positions against the truth, over
    the submerged time, as :func:`score` takes it: for tracks that are not navd's
    outputs (the numpy floor of bench-replay)."""
    truth_at = TruthAt(truth)
    sq = []
    for t, lat, lon in points:
        tr = truth_at(t)
        if tr is not None and tr.depth >= _SUBMERGED_DEPTH_M:
            sq.append(math.hypot(*_ne_error(lat, lon, tr.lat, tr.lon)) ** 2)
    return math.sqrt(sum(sq) / len(sq)) if sq else math.nan


@dataclass(frozen=True, slots=True)
class AgainstBound:
    """A mission's published ellipses beside the Cramer-Rao bound's (navd/hil/bound.py)."""

    # the RMS of the published std (both axes together) and of the bound's, m, over the
    # submerged time both cover
    published_std_m: float
    bound_std_m: float
    # the fraction of that time the truth lies in a 95 % ellipse of the bound's covariance
    # drawn about the estimate: what an estimate this good would score were it as sure as
    # the bound allows, the yardstick for the published ellipse's in95
    inside95: float


def against_bound(
    outputs: Iterable[Output],
    truth: Sequence[TruthSample],
    ellipses: Sequence[tuple[float, float, float, float]],
) -> AgainstBound:
    """The submerged estimates against the bound's position covariance ``(t, var_n,
    var_e, cov_ne)`` at the bound's step at or after each estimate (its steps are a
    second apart)."""
    truth_at = TruthAt(truth)
    ts = [e[0] for e in ellipses]
    pub = bnd = 0.0
    inside: list[bool] = []
    estimates, _ = split_outputs(outputs)
    for o in estimates:
        tr = truth_at(o.t)
        i = bisect.bisect_left(ts, o.t)
        if tr is None or tr.depth < _SUBMERGED_DEPTH_M or i == len(ts):
            continue
        _, var_n, var_e, cov = ellipses[i]
        dn, de = _ne_error(o.lat, o.lon, tr.lat, tr.lon)
        inside.append(_mahalanobis2(dn, de, var_n, var_e, cov) <= CHI2_2DOF_95)
        pub += o.std_n**2 + o.std_e**2
        bnd += var_n + var_e
    if not inside:
        return AgainstBound(math.nan, math.nan, math.nan)
    n = len(inside)
    return AgainstBound(math.sqrt(pub / n), math.sqrt(bnd / n), float(np.mean(inside)))


def score(outputs: Iterable[Output], truth: Sequence[TruthSample]) -> Score:
    """A mission's outputs against the simulator's truth samples (truth.jsonl)."""
    truth_at = TruthAt(truth)
    errs, dr_errs, cur_errs, inside, fix_errs = [], [], [], [], []
    d2s: list[float] = []
    ok_inside: list[bool] = []
    last_sub: tuple[float, float, float, str] | None = None
    estimates, ranges = split_outputs(outputs)
    reacquired_at = [r.t for r in ranges if r.reason == "gate_reacquire"]
    after: list[bool] = []
    for o in estimates:
        tr = truth_at(o.t)
        if tr is None or tr.depth < _SUBMERGED_DEPTH_M:
            continue
        dn, de = _ne_error(o.lat, o.lon, tr.lat, tr.lon)
        e = math.hypot(dn, de)
        errs.append(e)
        d2 = _mahalanobis2(dn, de, o.std_n**2, o.std_e**2, o.cov_ne)
        inside.append(d2 <= CHI2_2DOF_95)
        d2s.append(d2)
        if any(0.0 <= o.t - t < REACQUIRED_S for t in reacquired_at):
            after.append(d2 <= CHI2_2DOF_95)
        if o.integrity == "ok":
            ok_inside.append(d2 <= CHI2_2DOF_99)
        cur_errs.append(math.hypot(o.current_n - tr.current_n, o.current_e - tr.current_e))
        dre = None
        if o.dr_lat is not None and o.dr_lon is not None:
            dre = math.hypot(*_ne_error(o.dr_lat, o.dr_lon, tr.lat, tr.lon))
            dr_errs.append(dre)
        if o.fix_lat is not None and o.fix_lon is not None:
            fix_errs.append(math.hypot(*_ne_error(o.fix_lat, o.fix_lon, tr.lat, tr.lon)))
        last_sub = (e, dre if dre is not None else math.nan, d2, o.integrity or "")
    reacq = replies_to_reacquire(ranges)
    if not errs:
        nan = math.nan
        return Score(nan, nan, nan, nan, nan, nan, nan, 0, 0, 0)
    a = np.array(errs)
    return Score(
        rms_m=float(np.sqrt(np.mean(a**2))),
        p95_m=float(np.percentile(a, 95)),
        surfacing_m=last_sub[0] if last_sub else math.nan,
        inside95=float(np.mean(inside)),
        current_rms_mps=float(np.sqrt(np.mean(np.array(cur_errs) ** 2))),
        dr_rms_m=float(np.sqrt(np.mean(np.array(dr_errs) ** 2))) if dr_errs else math.nan,
        dr_surfacing_m=last_sub[1] if last_sub else math.nan,
        accepted=sum(1 for r in ranges if r.accepted),
        rejected=sum(1 for r in ranges if not r.accepted),
        reacquisitions=sum(1 for r in ranges if r.reason == "gate_reacquire"),
        fix_rms_m=float(np.sqrt(np.mean(np.array(fix_errs) ** 2))) if fix_errs else math.nan,
        fix_coverage=len(fix_errs) / len(errs),
        reacquire_replies_max=float(max(reacq)) if reacq else math.nan,
        ok_inside99=float(np.mean(ok_inside)) if ok_inside else math.nan,
        ok_fraction=len(ok_inside) / len(errs),
        reacquired_inside95=float(np.mean(after)) if after else math.nan,
        reacquired_estimates=len(after),
        nees=float(np.mean(d2s)) / 2.0,
        surfacing_d2=last_sub[2] if last_sub else math.nan,
        surfacing_integrity=last_sub[3] if last_sub else "",
    )
