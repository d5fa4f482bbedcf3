"""What a current that changes faster than a filter assumes adds to its position's uncertainty.

A filter's current walk sets both its gains and its covariance.  Widened, it makes a
single-beacon filter learn across the line of sight from ranges that say nothing there,
and its mean worse (BENCHMARKS.md, "The uncalibrated belief's current walk").  Kept
narrow, the covariance claims the water changes no faster than the walk, and a tidal
stream that turns during the mission carries the vehicle outside the ellipse.

A consider covariance keeps both (Schmidt's consider analysis; Bar-Shalom, Li and
Kirubarajan 2001, 5.6): the filter runs with its own walk, and beside it ``D`` follows
the error that an extra walk of the current would add, through the filter's own
transitions and gains (its Joseph form without the measurement noise, which ``P``
already holds).  ``P + D`` is then the covariance of the filter's estimate were the water
to change that much faster; the estimate itself is unchanged.

Ranges that see the water change in every direction (a net of transponders) need no such
allowance: the filter then carries the walk in its own gains
(``RangeFusion.carry_considered_walk``).

``D`` covers position and current (north, east, each), the states the extra walk drives
directly; what it would add to heading bias and speed scale through later gains is left
out.  Between measurements the transition is exact: position integrates the current.
"""

from __future__ import annotations

import math

import numpy as np


class CurrentConsider:
    def __init__(self, extra_walk_mps_per_sqrt_s: float) -> None:
        """``extra_walk``: the walk the water may have beyond the filter's own (m/s/sqrt s)."""
        self.q2 = max(0.0, extra_walk_mps_per_sqrt_s) ** 2
        self.t = 0.0
        # D over (dn, de, dc_n, dc_e), metres and m/s, row-major as floats: an estimate
        # reads it at every tick, a range rewrites it every few seconds
        self._flat = [0.0] * 16

    def set_walk(self, extra_walk_mps_per_sqrt_s: float, t: float) -> None:
        """Allow for another extra walk from ``t`` on; the error followed until then stays."""
        w = extra_walk_mps_per_sqrt_s
        q2 = w * w if w > 0.0 else 0.0  # NaN is no walk; a huge one overflows to inf
        if q2 == self.q2 or not (math.isfinite(w) and math.isfinite(q2)):
            return
        D = self.covariance(t)
        if np.isfinite(D).all():
            self._flat = [float(v) for v in D.ravel()]
            self.t = max(self.t, t)
        self.q2 = q2

    @property
    def walk(self) -> float:
        """The extra walk allowed for (m/s/sqrt s)."""
        return math.sqrt(self.q2)

    def reset(self, t: float) -> None:
        """A position and current fixed without this error (GPS, a re-acquisition's fit)."""
        self.t = t
        self._flat = [0.0] * 16

    def covariance(self, t: float) -> np.ndarray:
        """``D`` at ``t`` over (dn, de, dc_n, dc_e)."""
        dt = max(0.0, t - self.t)
        D: np.ndarray = np.array(self._flat).reshape(4, 4)
        if dt == 0.0:
            return D
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        D = F @ D @ F.T
        # the integrated random walk's noise over dt (current, and the position it drives)
        q = self.q2
        for i in (0, 1):
            D[i, i] += q * dt * dt * dt / 3.0
            D[i, i + 2] += q * dt * dt / 2.0
            D[i + 2, i] += q * dt * dt / 2.0
            D[i + 2, i + 2] += q * dt
        return D

    def update(self, t: float, K: np.ndarray, H: np.ndarray) -> None:
        """A scalar measurement fused with gain ``K`` and Jacobian ``H`` (the filter's, over
        the four states here first)."""
        if not (math.isfinite(t) and np.isfinite(K[:4]).all() and np.isfinite(H[:4]).all()):
            return  # a broken update tells nothing of this error
        with np.errstate(over="ignore", invalid="ignore"):
            D = self.covariance(t)
            A = np.eye(4) - np.outer(K[:4], H[:4])
            D = A @ D @ A.T
        if not np.isfinite(D).all():
            return
        self.t = t
        self._flat = (0.5 * (D + D.T)).ravel().tolist()

    def position(self, t: float) -> tuple[float, float, float]:
        """The extra (var_n, var_e, cov_ne) at ``t``, m^2: ``covariance``'s position block in
        scalars, since an estimate asks for it at every tick."""
        dt = max(0.0, t - self.t)
        d = self._flat
        walk = self.q2 * dt * dt * dt / 3.0
        dt2 = dt * dt
        return (
            d[0] + 2.0 * dt * d[2] + dt2 * d[10] + walk,
            d[5] + 2.0 * dt * d[7] + dt2 * d[15] + walk,
            d[1] + dt * (d[3] + d[6]) + dt2 * d[11],
        )

