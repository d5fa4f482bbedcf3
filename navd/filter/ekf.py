"""The ``default`` mode: navd's own single-beacon range EKF.

Geodetic nominal state, as in the thesis, with an error state in metres
(navd/filter/ekf_core.py):

* ``c_n, c_e`` water current north/east in m/s (the thesis carried rad/s).
* ``b`` heading bias added to the declination-corrected compass heading (the
  Chesapeake runs had an uncalibrated AHRS).
* ``s`` speed scale on the RPM-derived surge speed (the RPM map comes from a trial).
* ``o_n, o_e`` error of the position the beacon reports (true minus reported), a
  first-order Gauss-Markov process with the beacon's ``position_std_m`` and
  ``position_corr_s``.  A boat's GPS wanders slowly: treated as white range
  noise, its error made the filter overconfident (BENCHMARKS.md, consistency).

What it changes from the thesis, and why: the round trip's range geometry, a
chi-square gate and re-acquisition from consistent evidence (navd/filter/ekf_ranges.py);
here, the Joseph-form update, a symmetrised covariance, and positions moved along
geodesics.
"""

from __future__ import annotations

import math

import numpy as np

from navd import geodesy
from navd.filter import ekf_step
from navd.filter.common import Corrections, Held, StateEstimate
from navd.filter.ekf_core import CAL_MEAN_S, N_STATES
from navd.filter.ekf_ranges import RangeFusion
from navd.filter.lsfix import Fix
from navd.settings import NoiseConfig

__all__ = ["N_STATES", "RangeEKF"]

_OFFSET_PRIOR_M2 = 1.0  # offset variance before any beacon is seen (unobserved, keeps P invertible)


class RangeEKF(RangeFusion):
    ranges_as_reported = False
    ranges_only_without_gps = False

    def with_noise(self, noise: NoiseConfig) -> RangeEKF:
        """A fresh filter with this one's gates and site limit, and another noise model."""
        twin = RangeEKF(
            noise,
            self.gate_chi2,
            self.gate_chi2_long,
            self.reacquire_after,
            self.max_current,
            self.relinearise_ranges,
            self.sound_speed_rel_std,
        )
        twin.tide = self.tide
        return twin

    # -- initialisation and GPS -------------------------------------------------------
    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        nz = self.noise
        # the current's prior mean: the crew's tidal prediction where there is one
        self._tide_v = self._tide_at(t)
        self._tide_clock = None if self.tide is None else self.tide.offset_s
        cn, ce = self._tide_v or (0.0, 0.0)
        self.x = np.array([lat, lon, cn, ce, 0.0, 1.0, 0.0, 0.0])
        self.P = np.diag(
            [
                std_m**2,
                std_m**2,
                nz.current_init_std_mps**2,
                nz.current_init_std_mps**2,
                math.radians(nz.heading_bias_init_std_deg) ** 2,
                nz.speed_scale_init_std**2,
                _OFFSET_PRIOR_M2,
                _OFFSET_PRIOR_M2,
            ]
        )
        self.initialised = True
        self.t = t
        self.path[0] = t
        self.t_anchor = t
        self._forget_ranges()  # ranges from before would not chain to this state
        self._outage = None  # the offset states start again at their prior
        self.biases.restart(self.path)
        self._fused_extra = self.range_noise.extra_var  # the biases at their priors
        self.history.add(t, np.eye(N_STATES), self.x.copy(), self.P.copy())

    def checkpoint(self) -> tuple[np.ndarray, np.ndarray, Held]:
        """The state, and the covariance with what the range biases' uncertainty adds to
        it folded in: the resumed filter holds no sensitivity to them yet."""
        s, m, added = self.biases.held(self.path)
        P = self.P + added
        return (
            self.x.copy(),
            P,
            Held((s, m), self.outage_held(), self.long_refused_held(), self.range_noise.held()),
        )

    def restore(
        self, x: np.ndarray, P: np.ndarray, grow_m2: float, held: Held | None = None
    ) -> None:
        """A checkpoint's state (a restart), its position variance grown by ``grow_m2``;
        the range scale as it held it, or back at its prior if it held none; the tracked
        beacon's outage as it was, if one was under way; how often replies read long."""
        held = held or Held()
        self.x, self.P = x.copy(), P.copy()
        # the checkpoint's current is taken as it is: the stream's change while navd was
        # down (minutes: centimetres a second) is left to the walk
        self._tide_v = None
        self.P[0, 0] += grow_m2
        self.P[1, 1] += grow_m2
        self._forget_ranges()
        if held.scale is None or not self.biases.resume(self.path, *held.scale):
            self.biases.restart(self.path)
        self.resume_outage(held.outage)
        self.resume_long_refused(held.long_refused)
        self.range_noise.resume(held.range_noise)
        self._fused_extra = self.range_noise.extra_var  # the checkpoint held its scale at it
        self.history.correct(self.x.copy(), self.P.copy())

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None:
        # The fix, seen from the estimate, is the innovation in metres north and east.
        e, n, _ = geodesy.enu_offset(self.x[0], self.x[1], hd, lat, lon, hd)
        H = np.zeros((2, N_STATES))
        H[0, 0] = H[1, 1] = 1.0
        R = np.eye(2) * std_m**2
        S = H @ self.P @ H.T + R
        K = np.linalg.solve(S, H @ self.P).T
        IKH = np.eye(N_STATES) - K @ H
        P = IKH @ self.P @ IKH.T + K @ R @ K.T
        self.P = 0.5 * (P + P.T)
        residual = np.array([n, e])
        self._apply(K @ residual, hd)
        self._limit_current()
        self.t_anchor = self.t
        self._shift(self.biases.fixed(self.path, K, H, residual, S), hd)
        self._forget_ranges(biases_too=False)
        self.history.correct(self.x.copy(), self.P.copy())

    # -- prediction --------------------------------------------------------------------
    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        """Propagate over ``dt`` with the compass heading (true north, radians) and RPM speed."""
        if self.primary is not None:
            # first-order Gauss-Markov error of the beacon's own GPS: its expected value
            # decays towards zero as the error it was learned from wanders away, so the
            # nominal offset decays with the same phi as the error state
            phi = math.exp(-dt / self._off_tau)
            q_off = self._off_std**2 * (1.0 - phi * phi)
        else:
            phi, q_off = 1.0, 0.0
        if self.tide is not None:
            self._follow_tide(t - 0.5 * dt)
        dn, de, u, cpsi, spsi = ekf_step.step(
            self.x, self.P, self._F, self._Q, dt, heading, speed, hd, phi, q_off, self._step_noise
        )
        self.track.step(t, dn, de)
        w = min(1.0, dt / CAL_MEAN_S)
        j = self.dv_dcal
        dn_db, de_db, dn_ds, de_ds = -u * spsi, u * cpsi, speed * cpsi, speed * spsi
        j[0] += w * (dn_db - j[0])
        j[1] += w * (dn_ds - j[1])
        j[2] += w * (de_db - j[2])
        j[3] += w * (de_ds - j[3])
        self.t = t
        path = self.path
        path[0] = t
        path[1] += dn_db * dt
        path[2] += de_db * dt
        path[3] += dn_ds * dt
        path[4] += de_ds * dt
        if self.primary is not None:
            path[5] += dt / self._off_tau
        if self.history.enabled:
            self.history.add(t, self._F.copy(), self.x.copy(), self.P.copy())

    # -- outputs and smoother hooks ----------------------------------------------------
    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate:
        lat, lon, cn, ce = x[:4].tolist()
        (pnn, pne), (_, pee) = P[:2, :2].tolist()
        return StateEstimate(lat, lon, cn, ce, pnn, pee, pne)

    def estimate(self) -> StateEstimate:
        # estimate_of's reading inline: each tick asks twice (the bank's two beliefs)
        lat, lon, cn, ce = self.x[:4].tolist()
        (pnn, pne), (_, pee) = self.P[:2, :2].tolist()
        dnn, dee, dne = self.biases.position(self.path)
        if self.consider is not None:
            nn, ee, ne = self.consider.position(self.t)
            dnn, dee, dne = dnn + nn, dee + ee, dne + ne
        return StateEstimate(lat, lon, cn, ce, pnn + dnn, pee + dee, pne + dne)

    def apply_fix(self, fix: Fix) -> None:
        """Ranges reach this mode one by one; the net's fix only starts it without GPS."""

    def corrections(self) -> Corrections | None:
        return Corrections(*self.x[4:8].tolist())
