"""The ranges' common scale error, estimated beside a filter that has no state for it.

Every range is the round trip times the configured sound speed, so a water column whose
mean speed differs makes every range too long or too short by the same fraction ``s``
(measured over true, less one; the configured sound speed over the water's, less one):
a scale error common to all replies, not noise that averages away (seed 000, 3.1.1;
seed 004 calls it the measurement's scale factor error).  A few metres per kilometre, it
moves a two-transponder fix by tens of metres where the circles cross at a shallow angle.

The filter keeps no state for ``s``.  Friedland's two-stage estimator (Friedland 1969,
"Treatment of bias in recursive filtering", IEEE Trans. Autom. Control 14(4)) gives
what a filter augmented with it would, from the filter as it is and a scalar beside it:

* ``psi``, the sensitivity of the filter's error to what is left of ``s`` (position and
  current, north and east), through the filter's own transitions and gains:
  ``psi <- (I - K H) psi + K r`` at a range of ``r`` (``r`` is the range's derivative in
  ``s``), ``(I - K H) psi`` at a GPS fix, which ``s`` does not touch;
* each range reaches the filter with the scale as estimated taken out, and its
  innovation is then ``a ds`` plus noise of the variance ``S`` the filter gives it, with
  ``ds`` what is left of the scale and ``a = r - H psi`` before the update (``-H psi``
  for a fix): a scalar Kalman filter on those innovations learns ``ds``;
* what it learns, ``delta``, goes to the scale, and ``-psi delta`` to the filter's state,
  which is then the augmented filter's estimate; its covariance is the filter's plus
  ``m psi psi'``, ``m`` the scale's variance.  Exact for a linear model
  (tests/test_range_scale.py); fed back, so that each range is linearised at the best
  estimate, not at the one that believes the configured sound speed (in a shallow
  two-transponder crossing that one drifts hundreds of metres).

With one beacon the scale is weakly observed and ``m`` stays near its prior, so this is
mostly the consider covariance of that prior (Bar-Shalom, Li and Kirubarajan 2001, 5.6);
with fixed transponders, whose circles disagree with each other unless scaled, it is
learned within minutes.  Position and current only: what ``s`` does to the heading bias
and speed scale through later gains is left out, as the current's consider leaves it.
"""

from __future__ import annotations

import math

import numpy as np


class RangeScale:
    def __init__(self, rel_std: float) -> None:
        """``rel_std``: the configured sound speed's one-sigma error over the sound speed."""
        self.var = max(0.0, rel_std) ** 2 if math.isfinite(rel_std) else 0.0
        self.s = 0.0  # the estimate of the scale error
        self.m = self.var  # its variance
        self.t = 0.0
        self._psi = [0.0, 0.0, 0.0, 0.0]  # (dn, de, dc_n, dc_e) per unit s

    def restart(self, t: float) -> None:
        """A filter started afresh (a start, a checkpoint without the scale): the scale
        back at its prior."""
        self.s, self.m = 0.0, self.var
        self.reset(t)

    def resume(self, t: float, s: float, m: float) -> bool:
        """A restart from a checkpoint that held the scale as ``s`` of variance ``m``
        (``held``); False, and the prior kept, if they cannot be a scale's."""
        if not (math.isfinite(s) and math.isfinite(m) and m >= 0.0 and 1.0 + s > 0.5):
            self.restart(t)
            return False
        self.s, self.m = s, min(m, self.var)
        self.reset(t)
        return True

    def held(self, t: float) -> tuple[float, float, np.ndarray]:
        """What a checkpoint keeps at ``t``: the scale, its variance, and what that
        variance adds to the filter's covariance of (north, east, current north, current
        east).  Folded into the checkpoint's covariance, it lets the resumed filter start
        the sensitivity afresh (``resume``) without claiming more than it knew."""
        psi = self._moved(t)
        return self.s, self.m, self.m * np.outer(psi, psi)

    def reset(self, t: float) -> None:
        """A position and current set without ranges to this error (a re-acquisition's
        fit): the estimate no longer carries it, the scale itself is what it was."""
        self.t = t
        self._psi = [0.0, 0.0, 0.0, 0.0]

    def _moved(self, t: float) -> np.ndarray:
        dt = max(0.0, t - self.t)
        pn, pe, cn, ce = self._psi
        return np.array([pn + dt * cn, pe + dt * ce, cn, ce])

    def corrected(self, range_m: float) -> float:
        """A range with the scale as estimated taken out."""
        return range_m / (1.0 + self.s)

    def spread(self, t: float, H: np.ndarray, range_m: float) -> float:
        """What the scale's uncertainty adds to the innovation variance of a range of
        ``range_m`` with Jacobian ``H`` at ``t`` (0 where either is broken)."""
        with np.errstate(over="ignore", invalid="ignore"):
            a = float(range_m - H[:4] @ self._moved(t))
        v = a * a * self.m
        return v if math.isfinite(v) else 0.0

    def ranged(self, t: float, K: np.ndarray, H: np.ndarray, range_m: float,
               residual: float, S: float) -> np.ndarray:  # fmt: skip
        """A range of ``range_m`` fused with gain ``K`` and Jacobian ``H`` (the filter's),
        its ``residual`` of variance ``S`` to the filter: what to add to the filter's
        (north, east, current north, current east) for what it taught of the scale."""
        if not (math.isfinite(t) and math.isfinite(range_m) and math.isfinite(residual)):
            return np.zeros(4)
        if not (np.isfinite(K[:4]).all() and np.isfinite(H[:4]).all() and S > 0.0):
            return np.zeros(4)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            psi = self._moved(t)
            a = range_m - float(H[:4] @ psi)
            g = self.m * a / (a * a * self.m + S)
            psi = psi - K[:4] * float(H[:4] @ psi) + K[:4] * range_m
            return self._learnt(t, psi, g * residual, self.m * (1.0 - g * a))

    def fixed(self, t: float, K: np.ndarray, H: np.ndarray, residual: np.ndarray,
              S: np.ndarray) -> np.ndarray:  # fmt: skip
        """A GPS fix fused with gain ``K`` (states x 2) and Jacobian ``H`` (2 x states),
        its ``residual`` (north, east) of covariance ``S`` to the filter: as ``ranged``."""
        if not (math.isfinite(t) and np.isfinite(K[:4]).all() and np.isfinite(H[:, :4]).all()):
            return np.zeros(4)
        if not (np.isfinite(residual).all() and np.isfinite(S).all()):
            return np.zeros(4)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            psi = self._moved(t)
            a = -(H[:, :4] @ psi)
            try:
                w = np.linalg.solve(S, a)
            except np.linalg.LinAlgError:
                return np.zeros(4)
            m = self.m / (1.0 + self.m * float(a @ w))
            psi = psi - K[:4] @ (H[:, :4] @ psi)
            return self._learnt(t, psi, m * float(w @ residual), m)

    def _learnt(self, t: float, psi: np.ndarray, delta: float, m: float) -> np.ndarray:
        shift = -psi * delta
        if not (np.isfinite(shift).all() and math.isfinite(m) and m >= 0.0):
            return np.zeros(4)
        if not 1.0 + self.s + delta > 0.5:
            return np.zeros(4)  # no water halves a sound speed: a broken step, not a scale
        self.t = t
        self._psi = psi.tolist()
        self.s += delta
        self.m = m
        return shift

    def position(self, t: float) -> tuple[float, float, float]:
        """What the scale's remaining uncertainty adds to (var_n, var_e, cov_ne), m^2:
        ``_moved``'s position in scalars, since an estimate asks for it at every tick."""
        dt = max(0.0, t - self.t)
        pn, pe, cn, ce = self._psi
        pn += dt * cn
        pe += dt * ce
        v = self.m
        return v * pn * pn, v * pe * pe, v * pn * pe
