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

    def reset(self, t: float) -> None:
        """A position and current fixed without this error (GPS, a re-acquisition's fit)."""
        self.t = t
        self._flat = [0.0] * 16

    def _moved(self, t: float) -> np.ndarray:
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
            D = self._moved(t)
            A = np.eye(4) - np.outer(K[:4], H[:4])
            D = A @ D @ A.T
        if not np.isfinite(D).all():
            return
        self.t = t
        self._flat = (0.5 * (D + D.T)).ravel().tolist()

    def position(self, t: float) -> tuple[float, float, float]:
        """The extra (var_n, var_e, cov_ne) at ``t``, m^2: ``_moved``'s position block in
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


class RangeScaleConsider:
    """What an error in the configured sound speed adds to the position's uncertainty.

    Every range is the round trip times the configured sound speed, so a water column
    whose mean speed differs by a fraction ``s`` makes every range ``r s`` too short or
    too long: a scale error common to all replies, not noise that averages away (seed
    000, 3.1.1; seed 004 calls it the measurement's scale factor error).  The filter has no
    state for it.  As for the current above, ``psi`` follows what a unit ``s`` does to the
    filter's error through its own transitions and gains (Bar-Shalom, Li and Kirubarajan
    2001, 5.6): ``psi <- (I - K H) psi - K h_s`` at a range, ``h_s = -r`` the range's
    derivative in ``s``, and ``(I - K H) psi`` at a GPS fix, which ``s`` does not touch.
    ``psi psi' var(s)`` is then added to the published covariance.  Position and current
    only, as for the current's consider.
    """

    def __init__(self, rel_std: float) -> None:
        """``rel_std``: the sound speed's one-sigma error over the sound speed."""
        self.var = max(0.0, rel_std) ** 2 if math.isfinite(rel_std) else 0.0
        self.t = 0.0
        self._psi = [0.0, 0.0, 0.0, 0.0]  # (dn, de, dc_n, dc_e) per unit s

    def reset(self, t: float) -> None:
        """A position and current set without ranges to this error (a start, a restart)."""
        self.t = t
        self._psi = [0.0, 0.0, 0.0, 0.0]

    def _moved(self, t: float) -> np.ndarray:
        dt = max(0.0, t - self.t)
        pn, pe, cn, ce = self._psi
        return np.array([pn + dt * cn, pe + dt * ce, cn, ce])

    def _set(self, t: float, psi: np.ndarray) -> None:
        if np.isfinite(psi).all():
            self.t = t
            self._psi = psi.tolist()

    def ranged(self, t: float, K: np.ndarray, H: np.ndarray, range_m: float) -> None:
        """A range of ``range_m`` fused with gain ``K`` and Jacobian ``H`` (the filter's)."""
        if not (math.isfinite(t) and math.isfinite(range_m)):
            return
        if not (np.isfinite(K[:4]).all() and np.isfinite(H[:4]).all()):
            return
        with np.errstate(over="ignore", invalid="ignore"):
            psi = self._moved(t)
            psi = psi - K[:4] * float(H[:4] @ psi) + K[:4] * range_m
        self._set(t, psi)

    def fixed(self, t: float, K: np.ndarray, H: np.ndarray) -> None:
        """A GPS fix fused with gain ``K`` (states x 2) and Jacobian ``H`` (2 x states)."""
        if not (math.isfinite(t) and np.isfinite(K[:4]).all() and np.isfinite(H[:, :4]).all()):
            return
        with np.errstate(over="ignore", invalid="ignore"):
            psi = self._moved(t)
            psi = psi - K[:4] @ (H[:, :4] @ psi)
        self._set(t, psi)

    def position(self, t: float) -> tuple[float, float, float]:
        """The extra (var_n, var_e, cov_ne) at ``t``, m^2."""
        dt = max(0.0, t - self.t)
        pn, pe, cn, ce = self._psi
        pn += dt * cn
        pe += dt * ce
        v = self.var
        return v * pn * pn, v * pe * pe, v * pn * pe
