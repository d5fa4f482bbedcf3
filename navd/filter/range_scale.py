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

* ``psi``, the sensitivity of the filter's error (all its states) to what is left of
  ``s``, through the filter's own transitions and gains: ``psi <- F psi`` between updates,
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
learned within minutes.

Between updates the filter's transitions multiply to the identity plus their sums, since
current, heading bias and speed scale stay put: the time, the water-relative motion's
derivatives in heading bias and speed scale, and the beacon offsets' decay.  The filter
keeps those sums as running totals (``Path``, navd/filter/ekf.py's predict), so ``F psi``
over any interval is their difference, at no cost per step here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

#: the filter's running totals at a moment: (t, the sums over its steps of dn/db, de/db,
#: dn/ds, de/ds, and of dt over the beacon offsets' time constant)
Path = Sequence[float]
N = 8  # the filter's states (navd/filter/ekf_core.py)


class RangeScale:
    def __init__(self, rel_std: float) -> None:
        """``rel_std``: the configured sound speed's one-sigma error over the sound speed."""
        self.var = max(0.0, rel_std) ** 2 if math.isfinite(rel_std) else 0.0
        self.s = 0.0  # the estimate of the scale error
        self.m = self.var  # its variance
        self._at: tuple[float, ...] = (0.0,) * 6  # the filter's path when psi was last set
        self._psi = np.zeros(N)  # the filter's error per unit s, there

    @property
    def t(self) -> float:
        return self._at[0]

    def restart(self, at: Path) -> None:
        """A filter started afresh (a start, a checkpoint without the scale): the scale
        back at its prior."""
        self.s, self.m = 0.0, self.var
        self.reset(at)

    def resume(self, at: Path, s: float, m: float) -> bool:
        """A restart from a checkpoint that held the scale as ``s`` of variance ``m``
        (``held``); False, and the prior kept, if they cannot be a scale's."""
        if not (math.isfinite(s) and math.isfinite(m) and m >= 0.0 and 1.0 + s > 0.5):
            self.restart(at)
            return False
        self.s, self.m = s, min(m, self.var)
        self.reset(at)
        return True

    def held(self, at: Path) -> tuple[float, float, np.ndarray]:
        """What a checkpoint keeps: the scale, its variance, and what that variance adds
        to the filter's covariance.  Folded into the checkpoint's covariance, it lets the
        resumed filter start the sensitivity afresh (``resume``) without claiming more
        than it knew."""
        with np.errstate(over="ignore", invalid="ignore"):
            psi = self._moved(at)
            return self.s, self.m, self.m * np.outer(psi, psi)

    def reset(self, at: Path) -> None:
        """A position and current set without ranges to this error (a re-acquisition's
        fit): the estimate no longer carries it, the scale itself is what it was."""
        self._at = tuple(at)
        self._psi = np.zeros(N)

    def _moved(self, at: Path) -> np.ndarray:
        """psi carried along the filter's transitions from where it was set to ``at``."""
        a, p = self._at, self._psi
        dt = max(0.0, at[0] - a[0])
        out = p.copy()
        out[0] += dt * p[2] + (at[1] - a[1]) * p[4] + (at[3] - a[3]) * p[5]
        out[1] += dt * p[3] + (at[2] - a[2]) * p[4] + (at[4] - a[4]) * p[5]
        decay = math.exp(-max(0.0, at[5] - a[5]))
        out[6] *= decay
        out[7] *= decay
        return out

    def corrected(self, range_m: float) -> float:
        """A range with the scale as estimated taken out."""
        return range_m / (1.0 + self.s)

    def spread(self, at: Path, H: np.ndarray, range_m: float) -> float:
        """What the scale's uncertainty adds to the innovation variance of a range of
        ``range_m`` with Jacobian ``H`` (0 where either is broken)."""
        with np.errstate(over="ignore", invalid="ignore"):
            a = float(range_m - H @ self._moved(at))
        v = a * a * self.m
        return v if math.isfinite(v) else 0.0

    def ranged(self, at: Path, K: np.ndarray, H: np.ndarray, range_m: float,
               residual: float, S: float) -> np.ndarray:  # fmt: skip
        """A range of ``range_m`` fused with gain ``K`` and Jacobian ``H`` (the filter's),
        its ``residual`` of variance ``S`` to the filter: what to add to the filter's state
        for what it taught of the scale."""
        if not (math.isfinite(at[0]) and math.isfinite(range_m) and math.isfinite(residual)):
            return np.zeros(N)
        if not (np.isfinite(K).all() and np.isfinite(H).all() and S > 0.0):
            return np.zeros(N)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            psi = self._moved(at)
            h_psi = float(H @ psi)
            a = range_m - h_psi
            g = self.m * a / (a * a * self.m + S)
            psi = psi + K * (range_m - h_psi)
            return self._learnt(at, psi, g * residual, self.m * (1.0 - g * a))

    def fixed(self, at: Path, K: np.ndarray, H: np.ndarray, residual: np.ndarray,
              S: np.ndarray) -> np.ndarray:  # fmt: skip
        """A GPS fix fused with gain ``K`` (states x 2) and Jacobian ``H`` (2 x states),
        its ``residual`` (north, east) of covariance ``S`` to the filter: as ``ranged``."""
        if not (math.isfinite(at[0]) and np.isfinite(K).all() and np.isfinite(H).all()):
            return np.zeros(N)
        if not (np.isfinite(residual).all() and np.isfinite(S).all()):
            return np.zeros(N)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            psi = self._moved(at)
            a = -(H @ psi)
            try:
                w = np.linalg.solve(S, a)
            except np.linalg.LinAlgError:
                return np.zeros(N)
            m = self.m / (1.0 + self.m * float(a @ w))
            psi = psi + K @ a
            return self._learnt(at, psi, m * float(w @ residual), m)

    def _learnt(self, at: Path, psi: np.ndarray, delta: float, m: float) -> np.ndarray:
        shift = -psi * delta
        if not (np.isfinite(shift).all() and math.isfinite(m) and m >= 0.0):
            return np.zeros(N)
        if not 1.0 + self.s + delta > 0.5:
            return np.zeros(N)  # no water halves a sound speed: a broken step, not a scale
        self._at = tuple(at)
        self._psi = psi
        self.s += delta
        self.m = m
        return shift

    def position(self, at: Path) -> tuple[float, float, float]:
        """What the scale's remaining uncertainty adds to (var_n, var_e, cov_ne), m^2:
        ``_moved``'s position in scalars, since an estimate asks for it at every tick."""
        a, p = self._at, self._psi.tolist()
        dt = max(0.0, at[0] - a[0])
        pn = p[0] + dt * p[2] + (at[1] - a[1]) * p[4] + (at[3] - a[3]) * p[5]
        pe = p[1] + dt * p[3] + (at[2] - a[2]) * p[4] + (at[4] - a[4]) * p[5]
        v = self.m
        return v * pn * pn, v * pe * pe, v * pn * pe
