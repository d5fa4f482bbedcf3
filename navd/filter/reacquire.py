"""Re-acquisition from consistent evidence: a robust fit over the recent ranges.

When the gate keeps rejecting ranges, either the estimate has drifted (the
seed-000 Chesapeake run: a current prior too small, every range refused) or the
ranges are bad (multipath bursts, which only lengthen a path).  Widening the
covariance until ranges pass cannot tell the two apart: a burst of long outliers
then opens the gate to more of them, and the current runs away.

Instead, a correction of the present position and current is looked for that
explains the recent ranges *together*: each range, measured at its own time, is
predicted from the present estimate moved back along the dead-reckoned track,
plus the hypothesised position offset ``d`` and current error ``dc`` (a range
``lag`` seconds old sees the vehicle ``lag * dc`` further back).  Candidates are
fitted by Gauss-Newton on random minimal sets of ranges (RANSAC, Fischler and
Bolles 1981), scored by how many ranges agree within three sigma, and the best
is refitted on its inliers.  It is accepted only when

* enough ranges agree (``min_support``, and two thirds of the window), among them
  enough of those the gate refused, twice as many when all of those read long,
* the agreeing ranges fix the position (its standard deviation is bounded), and
* the current it implies is one water can have at this site (``max_current_mps``),
* no range reads shorter than it predicts by more than the noise allows: multipath
  only ever lengthens a path, so the ranges that disagree with a true correction
  all read long.  A wrong one, bent through a burst of long replies, leaves real
  ranges reading short.

Multipath replies are long by unrelated amounts, so they do not agree with each
other on any one hypothesis; real ranges from a drifted estimate all do.

The fit weighs the ranges by their errors' joint covariance, not each alone: the error
of a beacon's reported position is shared by its replies over its correlation time, and
a scale error by all of them.  Weighed as independent, the window's dozen replies to one
boat claimed a position and current about twice as sure as they were, and the truth left
the re-acquired ellipse (BENCHMARKS.md, "Honest uncertainty near the bound").  And it weighs
a range that reads long beyond ``HUBER_K`` sigma as the filter does one inside its gate:
multipath a few metres long agrees within three sigma, and at full weight bends the fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navd.filter.common import HUBER_K

_ITERATIONS = 8
_SUBSETS = 40
_INLIER_SIGMA = 3.0
_CURRENT_PRIOR_FRAC = 0.25  # one sigma of a current correction, at most, of the site's maximum
_CURRENT_FLOOR_MPS = 0.02  # ... and at least (a current learnt to nothing can still move)
# a filter that does not trust the current it knows allows this many times its std, and
# at least this much
_DOUBTED_MARGIN = 3.0
_DOUBTED_FLOOR_MPS = 0.1
_WANDER_MPS = 0.05  # drift not explained by a constant current error (bias, scale)
_LR_CHI2_4DOF_99 = 13.28  # 99 % quantile of chi-square, four degrees of freedom
_MAJORITY = 2.0 / 3.0  # of the window that must agree on a correction
_SHORT_ALLOWED = 1  # ranges reading short beyond the noise a correction may leave
_REFLECTOR_MAX = 0.5  # the weight a reflector's explanation gets, at most (see find)


@dataclass(frozen=True, slots=True)
class Ray:
    """One recent range, in metres north/east/up of the present estimate."""

    beacon: tuple[float, float, float]  # beacon position (up relative to the vehicle)
    ping: tuple[float, float]  # where dead reckoning puts the vehicle when the ping left
    reply: tuple[float, float]  # ... and when the reply arrived
    lag_ping: float  # seconds from then to now
    lag_reply: float
    range_m: float
    sigma_m: float  # all of its error: the range's own and its beacon's position's
    rejected: bool  # the gate refused it under the present estimate
    source: str  # the beacon's name
    beacon_std_m: float  # the part of sigma_m that is its beacon's position error
    beacon_corr_s: float  # ... and that error's correlation time (inf: a constant)
    predicted_std_m: float = 0.0  # the part of sigma_m that is a predicted beacon's error
    predicted_from: float = math.nan  # ... and the time of the report it was predicted from


@dataclass(frozen=True, slots=True)
class Hypothesis:
    d_north: float
    d_east: float
    dc_north: float
    dc_east: float
    cov: np.ndarray  # 4 x 4 over (d_north, d_east, dc_north, dc_east)
    inliers: int
    window: int


class _Rays:
    def __init__(self, rays: list[Ray], scale_var: float) -> None:
        self.B = np.array([r.beacon for r in rays])
        self.O = np.array([r.ping for r in rays])
        self.R = np.array([r.reply for r in rays])
        self.lo = np.array([r.lag_ping for r in rays])
        self.lb = np.array([r.lag_reply for r in rays])
        self.z = np.array([r.range_m for r in rays])
        self.sig = np.array([r.sigma_m for r in rays])
        self.rejected = np.array([r.rejected for r in rays])
        # What the rays share: a beacon's position error, correlated over its time (a
        # boat's GPS wanders over minutes, a surveyed transponder's error never does),
        # and the ranges' scale error, common to all.  Fitted as if independent, twelve
        # rays from one beacon would claim to average both away.
        std = np.array([r.beacon_std_m for r in rays])
        corr = np.array([r.beacon_corr_s for r in rays])
        names = np.array([r.source for r in rays])
        same = names[:, None] == names[None, :]
        lag = np.abs(self.lb[:, None] - self.lb[None, :])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            rho = np.where(lag == 0.0, 1.0, np.exp(-lag / np.maximum(corr, 1e-9)[:, None]))
        self.shared = np.where(same, rho, 0.0) * np.outer(std, std)
        # A beacon predicted through its location line's outage is one extrapolation from
        # its last report: the error of the velocity it was carried at grows with the time
        # since and is every prediction's, so the replies of one outage share it whole.
        pred = np.array([r.predicted_std_m for r in rays])
        start = np.array([r.predicted_from for r in rays])
        outage = same & (start[:, None] == start[None, :])  # NaN, not predicted: never
        pred = np.where(np.isfinite(start) & np.isfinite(pred), pred, 0.0)  # else its own
        self.shared += np.where(outage, np.outer(pred, pred), 0.0)
        self.own = np.maximum(self.sig**2 - std**2 - pred**2, 0.0)
        self.scale_var = scale_var if math.isfinite(scale_var) and scale_var > 0.0 else 0.0

    def weights(self, J: np.ndarray, idx: np.ndarray, long: np.ndarray) -> np.ndarray | None:
        """The inverse covariance of the errors of rays ``idx``, whose Jacobian is ``J``:
        a beacon's position error reaches each range along its line of sight, the scale's
        in proportion to its length; ``long``, the variance each range's own error is
        widened by as a long residual (``_long_variance``)."""
        sight = J[:, :2]
        z = self.z[idx]
        R = self.shared[np.ix_(idx, idx)] * (sight @ sight.T) + self.scale_var * np.outer(z, z)
        # the beacon's error along the line of sight is all of it (sight is a unit
        # vector but for the depth's share), as sigma_m counts it
        R[np.diag_indices_from(R)] = (
            self.own[idx] + long + self.shared[idx, idx] + self.scale_var * z**2
        )
        try:
            W: np.ndarray = np.linalg.inv(R)
        except np.linalg.LinAlgError:
            return None
        return W if np.all(np.isfinite(W)) else None

    def predict(self, th: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted ranges of rays ``idx`` under ``th`` and their Jacobian (n x 4)."""
        d, dc = th[:2], th[2:]
        B = self.B[idx]
        vo = B[:, :2] - (self.O[idx] + d - self.lo[idx, None] * dc)
        vb = B[:, :2] - (self.R[idx] + d - self.lb[idx, None] * dc)
        up2 = B[:, 2] ** 2
        ro = np.sqrt((vo**2).sum(axis=1) + up2)
        rb = np.sqrt((vb**2).sum(axis=1) + up2)
        # a beacon exactly overhead has no horizontal gradient; keep the division finite
        uo = vo / np.maximum(ro, 1e-6)[:, None]
        ub = vb / np.maximum(rb, 1e-6)[:, None]
        J = np.empty((len(idx), 4))
        J[:, :2] = -0.5 * (uo + ub)
        J[:, 2:] = 0.5 * (self.lo[idx, None] * uo + self.lb[idx, None] * ub)
        return 0.5 * (ro + rb), J

    def fit(
        self, idx: np.ndarray, prior: np.ndarray, joint: bool = True
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Gauss-Newton from no correction; (theta, covariance) or None if it fails.
        Without ``joint``, each range weighed alone: enough to propose a hypothesis, at a
        fraction of the cost."""
        th = np.zeros(4)
        N = prior
        w = 1.0 / self.sig[idx] ** 2
        for _ in range(_ITERATIONS):
            pred, J = self.predict(th, idx)
            res = self.z[idx] - pred
            if joint:
                W = self.weights(J, idx, self._long_variance(res, idx))
                if W is None:
                    return None
                JW = J.T @ W
                N = JW @ J + prior
                g = JW @ res - prior @ th
            else:
                N = J.T @ (w[:, None] * J) + prior
                g = J.T @ (w * res) - prior @ th
            try:
                step = np.linalg.solve(N, g)
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(step)):
                return None
            th = th + step
            if float(np.abs(step[:2]).max()) < 1e-3:
                break
        try:
            cov = np.linalg.inv(N)
        except np.linalg.LinAlgError:
            return None
        return th, cov

    def _long_variance(self, res: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """What a range reading long by more than ``HUBER_K`` sigma adds to its variance
        so that it pulls as a Huber M-estimator lets it (the filter's own rule for a long
        range inside its gate, navd/filter/ekf_ranges.py): multipath a few metres long
        is inside the inlier threshold, and at full weight a handful of such replies in
        a window bend the current the fit hands the filter."""
        sig = self.sig[idx]
        extra: np.ndarray = np.where(res > HUBER_K * sig, res * sig / HUBER_K - sig * sig, 0.0)
        return extra

    def cost(self, th: np.ndarray) -> float:
        """Sum of squared normalised residuals, each capped as an outlier's would be."""
        pred, _ = self.predict(th, np.arange(len(self.z)))
        return float(np.sum(np.minimum(((self.z - pred) / self.sig) ** 2, _INLIER_SIGMA**2)))

    def inliers(self, th: np.ndarray) -> np.ndarray:
        pred, _ = self.predict(th, np.arange(len(self.z)))
        inside: np.ndarray = np.abs(self.z - pred) <= _INLIER_SIGMA * self.sig
        return inside


def _drift_prior(
    pos_cov: np.ndarray,
    cur_cov: np.ndarray,
    since_s: float,
    max_current_mps: float,
    cal_drift_cov: np.ndarray | None = None,
    trust_current: bool = True,
) -> np.ndarray:
    """Information on (d, dc) from how an estimate drifts.

    Since its last anchor (a GPS fix, a re-acquisition) an estimate drifts by the
    error of its current times the time elapsed, ``d = since * dc``, and by what its
    calibration's error makes of the speed through the water, give or take its
    covariance at the anchor and a slower wander.  So a correction far from the
    estimate needs a current or calibration error to match, and a burst of outliers
    cannot pull the position without pulling the current past what is known of it.

    The calibration's drift, ``cal_drift_cov`` (its velocity covariance, m^2/s^2), is
    the filter's calibration covariance carried through the window's calibration
    Jacobian.  The current error's prior, at most a quarter of the site's maximum, is
    what the filter knows of its current: its own std (at least ``_CURRENT_FLOOR_MPS``)
    when it trusts it (``trust_current``), as the bank's config belief does.  Allowed
    three times that and at least 0.1 m/s, a run of replies from one boat whose GPS was
    off along the line of sight read as a current error the surface's fixes had ruled
    out, and the estimate then drifted across the line of sight for the rest of the dive
    (BENCHMARKS.md, "A re-acquisition keeps the current it knows").  The bank's
    uncalibrated belief keeps that margin (``_DOUBTED_MARGIN``, ``_DOUBTED_FLOOR_MPS``):
    it learns its heading bias and speed scale from the ranges as it goes, and a
    current learnt beside them can be as wrong as they are; fitted to its own std,
    its re-acquisitions held a wrong current and the published ellipse lost the truth.
    """
    cur_std = math.sqrt(max(0.0, float(np.linalg.eigvalsh(cur_cov)[-1])))
    if trust_current:
        sc = max(cur_std, _CURRENT_FLOOR_MPS)
    else:
        sc = max(_DOUBTED_MARGIN * cur_std, _DOUBTED_FLOOR_MPS)
    sc = min(_CURRENT_PRIOR_FRAC * max_current_mps, sc)
    sc2 = sc * sc
    slack = _WANDER_MPS * since_s
    cov_d = pos_cov + (slack * slack + 1.0) * np.eye(2)
    if cal_drift_cov is not None and np.all(np.isfinite(cal_drift_cov)):
        cov_d = cov_d + since_s * since_s * cal_drift_cov
    W = np.linalg.inv(cov_d)
    A = np.hstack([np.eye(2), -since_s * np.eye(2)])  # d - since * dc
    info: np.ndarray = A.T @ W @ A + np.diag([0.0, 0.0, 1.0 / sc2, 1.0 / sc2])
    return info


def find(
    rays: list[Ray],
    current: tuple[float, float],
    pos_cov: np.ndarray,
    cur_cov: np.ndarray,
    since_anchor_s: float,
    max_current_mps: float,
    min_support: int,
    min_rejected: int,
    max_std_m: float,
    seed: int,
    scale_var: float = 0.0,
    long_refused: float = 0.0,
    cal_drift_cov: np.ndarray | None = None,
    trust_current: bool = True,
) -> Hypothesis | None:
    """The correction most of the recent ranges agree on, or None when they do not agree.

    It must also explain at least ``min_rejected`` of the ranges the gate refused:
    a correction the accepted ranges alone support is no news, and replacing a
    converged covariance by a fit over a few ranges would throw information away.
    ``scale_var`` is the variance of the ranges' scale error as the filter knows it;
    ``long_refused``, the fraction of recent replies the gate refused as reading long;
    ``cal_drift_cov``, the covariance of the velocity error the filter's calibration
    (heading bias, speed scale) makes; ``trust_current``, whether the filter's own
    current covariance is what the fit allows (see ``_drift_prior``).

    When no refused range it explains reads short (all long, or none refused: a fit on
    accepted ranges whose NIS said the covariance claimed too much), a reflector that
    lengthened them (a hull, a layer, for minutes) explains them as well, with no
    correction: such runs bent re-acquisitions by 20 to 40 m along the line of sight
    while the fit claimed 8 (BENCHMARKS.md, "A reflector's run of long replies").  Their
    sign cannot tell the two apart, and how often this site's replies read long is the
    chance of the second: the covariance about the fit's mean then holds the estimate it
    replaces with that weight (at most a half), ``cov + w th th^T``, the spread of the
    two explanations.
    """
    n = len(rays)
    if n < min_support:
        return None
    r = _Rays(rays, scale_var)
    if not (np.all(np.isfinite(r.B)) and np.all(np.isfinite(r.z)) and np.all(r.sig > 0)):
        return None
    prior = _drift_prior(
        pos_cov, cur_cov, since_anchor_s, max_current_mps, cal_drift_cov, trust_current
    )
    rng = np.random.default_rng(seed)
    k = min(n, 4)
    best: tuple[int, float, np.ndarray] | None = None
    subsets = [np.arange(n)] + [
        np.sort(rng.choice(n, size=k, replace=False)) for _ in range(_SUBSETS)
    ]
    for idx in subsets:
        res = r.fit(idx, prior, joint=False)
        if res is None:
            continue
        th = res[0]
        mask = r.inliers(th)
        count = int(mask.sum())
        spread = r.cost(th)
        if best is None or (count, -spread) > (best[0], -best[1]):
            best = (count, spread, mask)
    if best is None or best[0] < max(min_support, math.ceil(_MAJORITY * n)):
        return None
    idx = np.flatnonzero(best[2])
    res = r.fit(idx, prior)
    if res is None:
        return None
    th, cov = res
    mask = r.inliers(th)
    count = int(mask.sum())
    if count < max(min_support, math.ceil(_MAJORITY * n)):
        return None
    explained = mask & r.rejected
    pred0, _ = r.predict(np.zeros(4), np.arange(n))
    all_long = not np.any(explained & (r.z < pred0))
    if all_long:
        # every refused range it explains read long, which is also what a burst of
        # multipath looks like: ask for twice the evidence (a real drift keeps adding it)
        min_rejected *= 2
    if int(explained.sum()) < min_rejected:
        return None
    # It must explain the ranges significantly better than the estimate as it stands:
    # a likelihood-ratio test on the (outlier-truncated) cost, four parameters more.
    if r.cost(np.zeros(4)) - r.cost(th) < _LR_CHI2_4DOF_99:
        return None
    pred, _ = r.predict(th, np.arange(n))
    if int(np.sum(r.z - pred < -_INLIER_SIGMA * r.sig)) > _SHORT_ALLOWED:
        return None  # it leaves real ranges reading short: not a correction, a contortion
    pos_std = math.sqrt(max(0.0, float(np.linalg.eigvalsh(cov[:2, :2])[-1])))
    if not (math.isfinite(pos_std) and pos_std <= max_std_m):
        return None  # the agreeing ranges do not pin the position (one line of sight)
    if math.hypot(current[0] + th[2], current[1] + th[3]) > max_current_mps:
        return None
    cov = _with_reflector(cov, th, long_refused if all_long else 0.0)
    return Hypothesis(float(th[0]), float(th[1]), float(th[2]), float(th[3]), cov, count, n)


def _with_reflector(cov: np.ndarray, th: np.ndarray, long_refused: float) -> np.ndarray:
    """The fit's covariance about its mean, with "no correction, a reflector" weighed by
    how often replies read long (see :func:`find`)."""
    w = min(long_refused, _REFLECTOR_MAX)
    if not w > 0.0:  # NaN too: no evidence of reflectors
        return cov
    wider: np.ndarray = cov + w * np.outer(th, th)
    return wider
