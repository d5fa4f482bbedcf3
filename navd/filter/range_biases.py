"""Errors common to many ranges, estimated beside a filter that has no states for them:
the ranges' scale error, and the position error of each surveyed transponder but the one
the filter's own offset states track.

Every range is the round trip times the configured sound speed, so a water column whose
mean speed differs makes every range too long or too short by the same fraction ``s``
(measured over true, less one; the configured sound speed over the water's, less one):
a scale error common to all replies, not noise that averages away (seed 000, 3.1.1;
seed 004 calls it the measurement's scale factor error).  A few metres per kilometre, it
moves a two-transponder fix by tens of metres where the circles cross at a shallow angle.
A surveyed transponder's position error is the same for every reply too, and a vehicle
kilometres from its net sees every transponder in nearly one direction, where such errors
move the fix by several times their size (seed 004, 2.2).  Counted as range noise, new
with every reply, they would average away, and the filter would claim what no reply says.

The filter keeps no states for them.  Friedland's two-stage estimator (Friedland 1969,
"Treatment of bias in recursive filtering", IEEE Trans. Autom. Control 14(4)) gives what a
filter augmented with them would, from the filter as it is and a small filter beside it,
of the biases ``beta = (s, then north and east of each transponder's error)``:

* ``psi``, the sensitivity of the filter's error (all its states) to what is left of
  ``beta``, through the filter's own transitions and gains: ``psi <- F psi`` between
  updates, ``psi <- psi + K (c - H psi)`` at a range whose derivative in ``beta`` is ``c``
  (``r`` for ``s``, and minus the line of sight for its own transponder's error),
  ``psi - K H psi`` at a GPS fix, which no bias touches;
* each range reaches the filter with the biases as estimated taken out, and its
  innovation is then ``a' dbeta`` plus noise of the variance ``S`` the filter gives it,
  with ``a = c - (H psi)'``: a Kalman filter on those innovations learns ``dbeta``;
* what it learns, ``delta``, goes to the biases, and ``-psi delta`` to the filter's state,
  which is then the augmented filter's estimate; its covariance is the filter's plus
  ``psi M psi'``, ``M`` the biases' covariance.  Exact for a linear model
  (tests/test_range_biases.py); fed back, so that each range is linearised at the best
  estimate, not at the one that believes the configured sound speed (in a shallow
  two-transponder crossing that one drifts hundreds of metres).

With one beacon the scale is weakly observed and its variance stays near its prior, so
this is mostly the consider covariance of that prior (Bar-Shalom, Li and Kirubarajan 2001,
5.6); with fixed transponders, whose circles disagree with each other unless scaled and
placed right, they are learned within minutes as far as the geometry tells them apart.

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


class RangeBiases:
    def __init__(self, rel_std: float) -> None:
        """``rel_std``: the configured sound speed's one-sigma error over the sound speed
        (0: the scale is taken as known)."""
        self.var = max(0.0, rel_std) ** 2 if math.isfinite(rel_std) else 0.0
        self._beacons: dict[str, int] = {}  # a transponder's first slot in beta
        self.beta = np.zeros(1)
        self.M = np.array([[self.var]])
        self._prior = np.array([self.var])  # each bias's prior variance (M's diagonal at first)
        self._at: tuple[float, ...] = (0.0,) * 6  # the filter's path when psi was last set
        self._psi = np.zeros((N, 1))  # the filter's error per unit of each bias, there
        self._alone: tuple[float, ...] | None = None
        self._cache()

    def _cache(self) -> None:
        """What ``position`` needs, as floats: with the scale alone, its variance and
        psi's rows that reach the position (an estimate asks at every tick)."""
        alone = len(self.beta) == 1
        self._alone = (float(self.M[0, 0]), *self._psi[:6, 0].tolist()) if alone else None

    @property
    def s(self) -> float:
        """The ranges' scale error as estimated."""
        return float(self.beta[0])

    @property
    def m(self) -> float:
        """Its variance."""
        return float(self.M[0, 0])

    @property
    def t(self) -> float:
        return self._at[0]

    def restart(self, at: Path) -> None:
        """A filter started afresh (a start, a checkpoint without the scale): every bias
        back at its prior, the transponders' to be added as they are heard."""
        self._beacons = {}
        self.beta = np.zeros(1)
        self.M = np.array([[self.var]])
        self._prior = np.array([self.var])
        self.reset(at)

    def resume(self, at: Path, s: float, m: float) -> bool:
        """A restart from a checkpoint that held the scale as ``s`` of variance ``m``
        (``held``); False, and the prior kept, if they cannot be a scale's."""
        self.restart(at)
        if not (math.isfinite(s) and math.isfinite(m) and m >= 0.0 and 1.0 + s > 0.5):
            return False
        self.beta[0] = s
        self.M[0, 0] = min(m, self.var)
        self._cache()
        return True

    def held(self, at: Path) -> tuple[float, float, np.ndarray]:
        """What a checkpoint keeps: the scale, its variance, and what the biases'
        uncertainty adds to the filter's covariance.  Folded into the checkpoint's
        covariance, it lets the resumed filter start the sensitivity afresh (``resume``)
        without claiming more than it knew; the transponders' errors start again from
        their priors, as the ranges to them will tell them again."""
        with np.errstate(over="ignore", invalid="ignore"):
            psi = self._moved(at)
            return self.s, self.m, psi @ self.M @ psi.T

    def reset(self, at: Path) -> None:
        """A position and current set without ranges to these errors (a re-acquisition's
        fit): the estimate no longer carries them, the biases themselves are as they were."""
        self._at = tuple(at)
        self._psi = np.zeros((N, len(self.beta)))
        self._cache()

    def surveyed(self, beacon: str, std_m: float) -> None:
        """A transponder whose surveyed position is off by a constant error of ``std_m``
        per axis: its error becomes two biases, at that prior, when first heard."""
        if beacon in self._beacons or not (math.isfinite(std_m) and std_m > 0.0):
            return
        k = len(self.beta)
        self._beacons[beacon] = k
        self.beta = np.append(self.beta, (0.0, 0.0))
        M = np.zeros((k + 2, k + 2))
        M[:k, :k] = self.M
        M[k, k] = M[k + 1, k + 1] = std_m * std_m
        self.M = M
        self._prior = np.append(self._prior, (std_m * std_m, std_m * std_m))
        self._psi = np.hstack([self._psi, np.zeros((N, 2))])
        self._cache()

    def deweight(self, ratio: float) -> None:
        """The ranges turned out ``ratio`` times noisier than they were fused as (the
        range noise learnt beside the filter, navd/filter/range_noise.py, grew): what the
        biases learnt from them was claimed that many times too sure.  They are constants,
        with no process noise to forget an early overconfidence, so a scale learnt from the
        first minutes' ranges, before their noise was, would stay too sure all mission, and
        a vehicle far from its net, where scale and position trade along the line of sight,
        with it.  In information form M^-1 = M0^-1 + J, J what the ranges taught (M0 the
        priors); they taught J / ratio."""
        if not (math.isfinite(ratio) and ratio > 1.0):
            return
        known = np.flatnonzero(self._prior > 0.0)  # a zero prior is a bias taken as known
        if len(known) == 0:
            return
        sub = np.ix_(known, known)
        prior_info = np.diag(1.0 / self._prior[known])
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            try:
                info = np.linalg.inv(self.M[sub])
                M = np.linalg.inv(prior_info + (info - prior_info) / ratio)
            except np.linalg.LinAlgError:
                return
        M = 0.5 * (M + M.T)
        if not (np.isfinite(M).all() and np.diag(M).min() >= 0.0):
            return
        self.M[sub] = M
        self._cache()

    def offset(self, beacon: str) -> tuple[float, float] | None:
        """A surveyed transponder's position error as estimated (north, east, metres);
        None for a beacon that has none here."""
        k = self._beacons.get(beacon)
        return None if k is None else (float(self.beta[k]), float(self.beta[k + 1]))

    def jacobian(self, beacon: str, range_m: float, H: np.ndarray) -> np.ndarray:
        """A range's derivative in the biases: its length for the scale, and for its own
        transponder's error minus the line of sight (moving the transponder moves the
        range like moving the vehicle the other way)."""
        c = np.zeros(len(self.beta))
        c[0] = range_m
        k = self._beacons.get(beacon)
        if k is not None:
            c[k], c[k + 1] = -H[0], -H[1]
        return c

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

    def spread(self, at: Path, H: np.ndarray, c: np.ndarray) -> float:
        """What the biases' uncertainty adds to the innovation variance of a range with
        Jacobian ``H`` and derivative ``c`` in the biases (0 where either is broken)."""
        with np.errstate(over="ignore", invalid="ignore"):
            a = c - H @ self._moved(at)
            v = float(a @ self.M @ a)
        return v if math.isfinite(v) else 0.0

    def ranged(self, at: Path, K: np.ndarray, H: np.ndarray, c: np.ndarray,
               residual: float, S: float) -> np.ndarray:  # fmt: skip
        """A range fused with gain ``K`` and Jacobian ``H`` (the filter's), derivative
        ``c`` in the biases, its ``residual`` of variance ``S`` to the filter: what to add
        to the filter's state for what it taught of the biases."""
        if not (math.isfinite(at[0]) and math.isfinite(residual) and S > 0.0):
            return np.zeros(N)
        if not (np.isfinite(K).all() and np.isfinite(H).all() and np.isfinite(c).all()):
            return np.zeros(N)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            psi = self._moved(at)
            a = c - H @ psi
            Ma = self.M @ a
            g = Ma / (float(a @ Ma) + S)
            psi = psi + np.outer(K, a)
            return self._learnt(at, psi, g * residual, self.M - np.outer(g, Ma))

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
            A = -(H @ psi)
            MA = self.M @ A.T
            try:
                G = np.linalg.solve(A @ MA + S, MA.T).T
            except np.linalg.LinAlgError:
                return np.zeros(N)
            psi = psi + K @ A
            return self._learnt(at, psi, G @ residual, self.M - G @ MA.T)

    def _learnt(self, at: Path, psi: np.ndarray, delta: np.ndarray, M: np.ndarray) -> np.ndarray:
        shift: np.ndarray = -(psi @ delta)
        if not (np.isfinite(shift).all() and np.isfinite(M).all() and np.diag(M).min() >= 0.0):
            return np.zeros(N)
        if not 1.0 + self.s + float(delta[0]) > 0.5:
            return np.zeros(N)  # no water halves a sound speed: a broken step, not a scale
        self._at = tuple(at)
        self._psi = psi
        self.beta = self.beta + delta
        self.M = 0.5 * (M + M.T)
        self._cache()
        return shift

    def position(self, at: Path) -> tuple[float, float, float]:
        """What the biases' remaining uncertainty adds to (var_n, var_e, cov_ne), m^2:
        an estimate asks for it at every tick, so the scale alone goes in scalars."""
        a = self._at
        dt = max(0.0, at[0] - a[0])
        db_n, db_e, ds_n, ds_e = at[1] - a[1], at[2] - a[2], at[3] - a[3], at[4] - a[4]
        if self._alone is not None:
            v, p0, p1, p2, p3, p4, p5 = self._alone
            pn = p0 + dt * p2 + db_n * p4 + ds_n * p5
            pe = p1 + dt * p3 + db_e * p4 + ds_e * p5
            return v * pn * pn, v * pe * pe, v * pn * pe
        p = self._psi
        with np.errstate(over="ignore", invalid="ignore"):
            rows = p[:2] + dt * p[2:4] + np.outer((db_n, db_e), p[4]) + np.outer((ds_n, ds_e), p[5])
            C = rows @ self.M @ rows.T
        return float(C[0, 0]), float(C[1, 1]), float(C[0, 1])
