"""A net of two transponders: the other crossing of their range circles.

Two ranges place the vehicle at either of two points, mirror images of each other
across the vertical plane through the transponders, from which every slant range to
both is the same.  Which side it is on, only the way it got there tells: the GPS
before the dive, then dead reckoning.  An EKF sees one side.  Linearised there, it
takes the circles' curvature for knowledge of the side: on a track along the baseline
of a net whose ranges were noisier than the config said, an estimate pushed across
the baseline by a wrong heading bias (its error 2.7 times the std across it) shrank
to 13 m about the wrong crossing, 166 m from the truth, and integrity said ``ok``
(BENCHMARKS.md, "The other crossing of two transponders' circles").

So while the ranges come from two transponders only, the filter keeps the other
crossing as a hypothesis of its own: a twin of the followed filter, its position and
covariance reflected across the baseline (a Gaussian sum for an ambiguous measurement,
Alspach and Sorenson 1972).  The twin is made with the weight the filter's own ellipse
puts beyond the baseline, ``Phi(-|c| / sigma_c)`` (``c`` the estimate's distance from
the baseline, ``sigma_c`` its std across it), and flown like the filter: the same dead
reckoning, its own gate and re-acquisition.  Dead reckoning is what tells the two
apart: the twin moves as the vehicle moves, not as its mirror image would, so where the
vehicle runs across the baseline the twin either follows it over and merges with the
filter or stops fitting the ranges and is let go.  Where it runs along the baseline
nothing tells them apart, and the twin stays at its weight: the ranges do not move it
(``MirrorTwin.weigh`` says why).

The published estimate is the filter's mean with the covariance of the mixture about
it, ``(1 - w) P + w (P_twin + d d^T)``: integrity degrades while the other crossing is
both far and likely.  While the twin lies within its own and the filter's ellipses of
the filter's mean, it is the same hypothesis, and it is made again from the filter's
ellipse as it is then; a GPS fix, a restart or a third transponder ends it.  The mean
is never moved to the twin's: the net's replies cannot say which of the two is right.
"""

from __future__ import annotations

import copy
import math
from collections import deque

import numpy as np

from navd import geodesy
from navd.filter.common import History, RangeMeas, StateEstimate, spread_about
from navd.filter.ekf import RangeEKF

# the ranges that say which transponders the vehicle hears (a net of two: exactly two)
_RECENT_RANGES = 10
# transponders nearer than this define no baseline the ranges could mirror across
_MIN_BASELINE_M = 10.0
# the weight beyond the baseline below which no twin is made
_MIN_WEIGHT = 1e-3
# the squared distance (in the two ellipses summed) within which the twin is the
# filter's own hypothesis again
_MERGED_D2 = 1.0


def _phi_tail(z: float) -> float:
    """P(Z > z) for a unit normal Z."""
    return 0.5 * math.erfc(z / math.sqrt(2.0))


class MirrorTwin:
    """The other crossing of a two-transponder net's circles, as a filter of its own."""

    def __init__(self) -> None:
        self.twin: RangeEKF | None = None
        self.w = 0.0  # the twin's weight
        self._lost = 0  # ranges in a row the twin refused and the followed filter took
        self._heard: deque[str] = deque(maxlen=_RECENT_RANGES)
        self._where: dict[str, tuple[float, float]] = {}  # each transponder's position

    def reset(self) -> None:
        """No twin: a GPS fix said the side, or the net is not two transponders, or the
        twin was lost, broken or merged."""
        self.twin = None
        self.w = 0.0
        self._lost = 0

    def forget(self) -> None:
        """A start or a restart: the transponders heard before are not this run's."""
        self.reset()
        self._heard.clear()
        self._where.clear()

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        if self.twin is not None:
            self.twin.predict(t, dt, heading, speed, hd)

    def _baseline(self) -> tuple[float, float, float, float] | None:
        """The baseline of the two transponders the recent ranges came from: a point of it
        (radians) and its unit normal (north, east); None unless exactly two, apart."""
        names = set(self._heard)
        if len(names) != 2:
            return None
        a, b = (self._where[n] for n in sorted(names))
        bn, be = geodesy.nearby_offset(a[0], a[1], b[0], b[1])
        length = math.hypot(bn, be)
        if not (math.isfinite(length) and length >= _MIN_BASELINE_M):
            return None
        return a[0], a[1], -be / length, bn / length

    def heard(self, m: RangeMeas) -> None:
        """A range of ``m.beacon``: which transponders are heard, and where they are."""
        if math.isfinite(m.beacon_lat) and math.isfinite(m.beacon_lon):
            self._heard.append(m.beacon)
            self._where[m.beacon] = (m.beacon_lat, m.beacon_lon)

    def weigh(self, m: RangeMeas, followed_accepted: bool, lost_after: int) -> None:
        """After the followed filter fused (or refused) ``m``: the twin takes the range
        too, and is let go once ``lost_after`` ranges in a row that the followed filter
        accepted it refused on their residuals, as dead reckoning across the baseline
        makes it.  Its weight is not moved by how well each predicts the ranges: the two
        crossings predict them alike, and what tells them apart per range is the noise
        and how far each filter has converged, which drove a twin 8 to 33 m from the
        truth to nothing while the followed filter sat 160 m off (BENCHMARKS.md)."""
        twin = self.twin
        if twin is None:
            return
        d = twin.range_update(m)
        if d.accepted:
            self._lost = 0
        elif d.on_residual and followed_accepted:
            self._lost += 1
        if self._lost >= lost_after or not (
            np.isfinite(twin.x).all() and np.isfinite(twin.P).all()
        ):
            self.reset()  # a lost or broken twin says nothing of the side

    def settle(self, followed: RangeEKF) -> None:
        """After a range: end the twin where the net is not two transponders, and make it
        again from the followed filter where it has merged with it (or there is none)."""
        line = self._baseline()
        if line is None:
            self.reset()
            return
        if self.twin is not None and not self._merged(followed, self.twin):
            return
        lat0, lon0, nn, ne = line
        n, e = geodesy.nearby_offset(lat0, lon0, float(followed.x[0]), float(followed.x[1]))
        c = n * nn + e * ne
        est = followed.estimate()
        var_c = nn * nn * est.var_n + ne * ne * est.var_e + 2.0 * nn * ne * est.cov_ne
        if not (math.isfinite(c) and math.isfinite(var_c) and var_c > 0.0):
            self.reset()
            return
        w = _phi_tail(abs(c) / math.sqrt(var_c))
        if w < _MIN_WEIGHT:
            self.reset()
            return
        self.twin = _reflected(followed, lat0, lon0, nn, ne, n - 2.0 * c * nn, e - 2.0 * c * ne)
        self.w = w
        self._lost = 0

    @staticmethod
    def _merged(a: RangeEKF, b: RangeEKF) -> bool:
        """Whether ``b``'s mean lies within the two filters' ellipses of ``a``'s."""
        n, e = geodesy.nearby_offset(float(a.x[0]), float(a.x[1]), float(b.x[0]), float(b.x[1]))
        S = a.P[:2, :2] + b.P[:2, :2]
        d = np.array([n, e])
        try:
            d2 = float(d @ np.linalg.solve(S, d))
        except np.linalg.LinAlgError:
            return False
        return math.isfinite(d2) and d2 < _MERGED_D2

    def mixed(self, est: StateEstimate) -> StateEstimate:
        """``est`` (the followed belief's, or the bank's mixture) with the twin's spread
        about its mean added at the twin's weight."""
        twin = self.twin
        if twin is None:
            return est
        return spread_about(est, twin.estimate(), self.w)


def _reflected(
    f: RangeEKF, lat0: float, lon0: float, nn: float, ne: float, n: float, e: float
) -> RangeEKF:
    """A copy of ``f`` at (``n``, ``e``) metres from (``lat0``, ``lon0``), the reflection
    of its position across the line through (``lat0``, ``lon0``) of unit normal (``nn``,
    ``ne``); its covariance reflected with it, and what the biases' uncertainty adds to
    it folded in (as a checkpoint folds it), since the copy starts their sensitivity
    afresh.  The ranges it remembers were fused on the other side, so it forgets them."""
    kept = f.history
    f.history = History()  # the smoother's file stays the followed filter's alone
    try:
        twin = copy.deepcopy(f)
    finally:
        f.history = kept
    _, P, _ = f.checkpoint()
    T = np.eye(len(f.x))
    T[:2, :2] = np.eye(2) - 2.0 * np.outer((nn, ne), (nn, ne))
    x = f.x.copy()
    x[0], x[1] = geodesy.offset_position(lat0, lon0, n, e)
    twin.P = T @ P @ T.T
    twin.move_to(x, np.zeros_like(P))
    return twin
