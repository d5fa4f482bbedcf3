"""The ``default`` mode: navd's own single-beacon range EKF.

Geodetic nominal state, as in the thesis, with an error state in metres:

    nominal  x = (lat, lon, c_n, c_e, b, s, o_n, o_e)
    error   dx = (dn, de, dc_n, dc_e, db, ds, do_n, do_e)
             metres, m/s, radians, scale, metres

* ``c_n, c_e`` water current north/east in m/s (the thesis carried rad/s).
* ``b`` heading bias added to the declination-corrected compass heading (the
  Chesapeake runs had an uncalibrated AHRS).
* ``s`` speed scale on the RPM-derived surge speed (the RPM map comes from a trial).
* ``o_n, o_e`` error of the position the beacon reports (true minus reported), a
  first-order Gauss-Markov process with the beacon's ``position_std_m`` and
  ``position_corr_s``.  A boat's GPS wanders slowly: treated as white range
  noise, its error made the filter overconfident (BENCHMARKS.md, consistency).
  Only the first beacon heard has these states; others add their position error
  to the range variance.

What it changes from the thesis, and why:

* Range geometry of the round trip: the request left at ``t_ping`` from where the
  vehicle was then and the reply reached it at ``t``; the predicted range is the mean
  of the out and back legs, the ping end found by undoing the dead-reckoned motion
  since ``t_ping`` (recorded per step), with its dependence on the current.
* Innovation gate on nu^2 / S (chi-square, one degree of freedom) instead of a
  one-sigma radius, tighter for ranges that read long (multipath only lengthens
  a path).  The gate follows the covariance (seed 003, 4.2.4), so a filter that
  has dead reckoned for long accepts wider.
* Re-acquisition from consistent evidence: when ``reacquire_after`` of the last
  ``2 * reacquire_after`` ranges were rejected, a robust fit over the recent
  ranges (``navd/filter/reacquire.py``) looks for the position and current
  correction most of them agree on.  Only such a correction is applied, with the
  fit's covariance; a burst of mutually inconsistent long replies finds none and
  changes nothing.  The current it learns is bounded by ``max_current_mps``.
* Joseph-form update, symmetrised covariance, positions moved along geodesics.
"""

from __future__ import annotations

import bisect
import math
from collections import deque

import numpy as np

from navd import geodesy
from navd.filter import reacquire
from navd.filter.common import (
    Corrections,
    GateDecision,
    History,
    RangeMeas,
    StateEstimate,
    joseph_update,
)
from navd.filter.integrity import chi2_quantile
from navd.filter.lsfix import Fix
from navd.settings import NoiseConfig

N_STATES = 8
_EYE = np.eye(N_STATES)
_OFFSET_PRIOR_M2 = 1.0  # offset variance before any beacon is seen (unobserved, keeps P invertible)
# Recent ranges the re-acquisition fit looks at, and the dead-reckoned track kept to
# place them (also the round-trip geometry of each range).
_WINDOW_S = 300.0
_WINDOW_RANGES = 12
_TRACK_SECONDS = _WINDOW_S
_HUBER_K = 1.5  # long residuals beyond this many sigma are down-weighted
_MIN_SUPPORT = 6  # ranges that must agree on a re-acquisition
_REACQUIRED_STD_M = 200.0  # a fit looser than this leaves the estimate as it is


class RangeEKF:
    ranges_as_reported = False
    ranges_only_without_gps = False

    def __init__(
        self,
        noise: NoiseConfig,
        gate_chi2: float,
        gate_chi2_long: float,
        reacquire_after: int,
        max_current_mps: float = 2.0,
    ) -> None:
        self.noise = noise
        self.max_current = max_current_mps
        self.gate_chi2 = gate_chi2
        self.gate_chi2_long = gate_chi2_long
        self.reacquire_after = reacquire_after
        self.x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
        self.P = np.eye(N_STATES)
        # the beacon whose reported-position error the offset states track, and its model
        self.primary: str | None = None
        self._off_std = 0.0
        self._off_tau = math.inf
        self.initialised = False
        self.history = History()
        # recent gate decisions: (accepted, residual); see _reacquire
        self._recent: deque[tuple[bool, float]] = deque(maxlen=2 * reacquire_after)
        self.reacquisitions = 0
        self.reacquire_refused = 0  # rejection streaks the recent ranges did not explain
        self.t_anchor = 0.0  # when the position was last pinned (GPS, re-acquisition)
        self._window: deque[tuple[RangeMeas, bool]] = deque(maxlen=_WINDOW_RANGES)
        self.last_nis = math.nan  # normalised innovation squared of the last range
        self.last_s = math.nan  # and its innovation variance (m^2)
        # NIS of the last accepted ranges, and the 99 % bound of their sum (chi-square)
        self._nis: deque[float] = deque(maxlen=2 * reacquire_after)
        self._nis_limit = chi2_quantile(0.99, 2 * reacquire_after)
        self.t = 0.0
        # cumulative dead-reckoned north/east displacement at each step time (round-trip model)
        self._track_t: deque[float] = deque()
        self._track_ne: deque[tuple[float, float]] = deque()
        self._cum_n = 0.0
        self._cum_e = 0.0

    def with_noise(self, noise: NoiseConfig) -> RangeEKF:
        """A fresh filter with this one's gates and site limit, and another noise model."""
        return RangeEKF(
            noise, self.gate_chi2, self.gate_chi2_long, self.reacquire_after, self.max_current
        )

    # -- initialisation and GPS -------------------------------------------------------
    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        nz = self.noise
        self.x = np.array([lat, lon, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
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
        self.t_anchor = t
        self.history.add(t, np.eye(N_STATES), self.x.copy(), self.P.copy())

    def restore(self, x: np.ndarray, P: np.ndarray, grow_m2: float) -> None:
        """A checkpoint's state (a restart), its position variance grown by ``grow_m2``."""
        self.x, self.P = x.copy(), P.copy()
        self.P[0, 0] += grow_m2
        self.P[1, 1] += grow_m2
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
        self._apply(K @ np.array([n, e]), hd)
        self._limit_current()
        self.t_anchor = self.t
        self._recent.clear()
        self._nis.clear()
        self._window.clear()  # ranges before a fix say nothing the fix does not
        self.history.correct(self.x.copy(), self.P.copy())

    # -- prediction --------------------------------------------------------------------
    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        """Propagate over ``dt`` with the compass heading (true north, radians) and RPM speed."""
        lat, lon, cn, ce, b, s = self.x[:6].tolist()
        psi = heading + b
        u = s * speed
        cpsi, spsi = math.cos(psi), math.sin(psi)
        vn = u * cpsi + cn
        ve = u * spsi + ce
        dn, de = vn * dt, ve * dt
        self.x[0], self.x[1] = geodesy.offset_position(lat, lon, dn, de, hd)
        self._cum_n += dn
        self._cum_e += de
        self._track_t.append(t)
        self._track_ne.append((self._cum_n, self._cum_e))
        while self._track_t and self._track_t[0] < t - _TRACK_SECONDS:
            self._track_t.popleft()
            self._track_ne.popleft()

        F = _EYE.copy()
        F[0, 2] = dt
        F[1, 3] = dt
        F[0, 4] = -u * spsi * dt
        F[1, 4] = u * cpsi * dt
        F[0, 5] = speed * cpsi * dt
        F[1, 5] = speed * spsi * dt

        nz = self.noise
        # Heading and speed errors are correlated over input_corr_s, so their effect on
        # position grows like a random walk with that time constant (first-order
        # Gauss-Markov, short correlation): q = sigma^2 * tau per second.
        tau = nz.input_corr_s
        var_along = (nz.speed_std_mps**2) * tau * dt
        var_cross = (u * math.radians(nz.heading_std_deg)) ** 2 * tau * dt
        if self.primary is not None:
            # first-order Gauss-Markov error of the beacon's own GPS: its expected value
            # decays towards zero as the error it was learned from wanders away, so the
            # nominal offset decays with the same phi as the error state
            phi = math.exp(-dt / self._off_tau)
            F[6, 6] = F[7, 7] = phi
            self.x[6] *= phi
            self.x[7] *= phi
        P = F @ self.P @ F.T
        P += P.T  # symmetric by construction; this removes the round-off
        P *= 0.5
        # Q, added in place: it is diagonal but for the along/cross-track position block
        P[0, 0] += var_along * cpsi * cpsi + var_cross * spsi * spsi
        P[1, 1] += var_along * spsi * spsi + var_cross * cpsi * cpsi
        q01 = (var_along - var_cross) * cpsi * spsi
        P[0, 1] += q01
        P[1, 0] += q01
        q_cur = nz.current_walk_mps_per_sqrt_s**2 * dt
        P[2, 2] += q_cur
        P[3, 3] += q_cur
        P[4, 4] += math.radians(nz.heading_bias_walk_deg_per_sqrt_s) ** 2 * dt
        P[5, 5] += nz.speed_scale_walk_per_sqrt_s**2 * dt
        if self.primary is not None:
            q_off = self._off_std**2 * (1.0 - phi * phi)
            P[6, 6] += q_off
            P[7, 7] += q_off
        self.P = P
        self.t = t
        if self.history.enabled:
            self.history.add(t, F, self.x.copy(), self.P.copy())

    def _displacement_since(self, t0: float) -> tuple[float, float]:
        """Dead-reckoned north/east displacement from ``t0`` to now."""
        ts = self._track_t
        if not ts or t0 >= ts[-1]:
            return 0.0, 0.0
        i = bisect.bisect_left(ts, t0)
        if i == 0:
            n0, e0 = self._track_ne[0]
        else:
            # the step ending at ts[i] covered (ts[i-1], ts[i]]: interpolate inside it
            ta, tb = ts[i - 1], ts[i]
            (na, ea), (nb, eb) = self._track_ne[i - 1], self._track_ne[i]
            w = (t0 - ta) / (tb - ta) if tb > ta else 1.0
            n0, e0 = na + w * (nb - na), ea + w * (eb - ea)
        return self._cum_n - n0, self._cum_e - e0

    # -- range update ------------------------------------------------------------------
    def predicted_range(self, m: RangeMeas) -> tuple[float, np.ndarray]:
        """Mean of the out and back legs of the round trip, and its Jacobian.

        The filter may already be past ``m.t`` (a reply completes only after its
        location line): both ends are found by undoing the dead-reckoned motion
        since them, so a late range is fused at its own time.
        """
        lat, lon = float(self.x[0]), float(self.x[1])
        dn_p, de_p = self._displacement_since(m.t_ping)
        dn_b, de_b = self._displacement_since(m.t)
        lat_p, lon_p = geodesy.offset_position(lat, lon, -dn_p, -de_p, m.vehicle_hd)
        lat_b, lon_b = geodesy.offset_position(lat, lon, -dn_b, -de_b, m.vehicle_hd)
        tracked = m.beacon == self.primary
        b_lat, b_lon = m.beacon_lat, m.beacon_lon
        if tracked:
            # where the beacon really is: its report corrected by the estimated offset
            b_lat, b_lon = geodesy.offset_position(
                b_lat, b_lon, float(self.x[6]), float(self.x[7]), m.beacon_hd
            )
        r_back, gn_b, ge_b = geodesy.range_and_gradient(
            lat_b, lon_b, m.vehicle_hd, b_lat, b_lon, m.beacon_hd
        )
        r_out, gn_o, ge_o = geodesy.range_and_gradient(
            lat_p, lon_p, m.vehicle_hd, b_lat, b_lon, m.beacon_hd
        )
        # each end lies (now - its time) seconds of current drift behind the estimate
        lag_o = max(0.0, self.t - m.t_ping)
        lag_b = max(0.0, self.t - m.t)
        H = np.zeros(N_STATES)
        H[0] = 0.5 * (gn_o + gn_b)
        H[1] = 0.5 * (ge_o + ge_b)
        H[2] = -0.5 * (lag_o * gn_o + lag_b * gn_b)
        H[3] = -0.5 * (lag_o * ge_o + lag_b * ge_b)
        if tracked:
            # moving the beacon moves the range like moving the vehicle the other way
            H[6] = -H[0]
            H[7] = -H[1]
        return 0.5 * (r_out + r_back), H

    def _track_beacon(self, m: RangeMeas) -> None:
        """Adopt the first beacon heard as the one whose position error is estimated."""
        if self.primary is not None or m.beacon_position_std_m <= 0.0:
            return
        self.primary = m.beacon
        self._off_std = m.beacon_position_std_m
        self._off_tau = m.beacon_position_corr_s
        self.P[6, 6] = self.P[7, 7] = self._off_std**2
        self.history.widen(self.P.copy())

    def range_update(self, m: RangeMeas) -> GateDecision:
        self._track_beacon(m)
        expected, H = self.predicted_range(m)
        r_var = m.std_m**2
        if m.beacon != self.primary:
            # another beacon's position error is not a state: count it as range noise
            r_var += m.beacon_position_std_m**2
        residual = m.range_m - expected
        S = float(H @ self.P @ H) + r_var
        chi2 = self.gate_chi2_long if residual > 0.0 else self.gate_chi2
        gate_m = math.sqrt(chi2 * S)
        self.last_s = S
        self.last_nis = residual * residual / S
        while self._window and m.t - self._window[0][0].t > _WINDOW_S:
            self._window.popleft()
        if residual * residual > chi2 * S:
            self._window.append((m, True))
            self._recent.append((False, residual))
            rejected = [r for ok, r in self._recent if not ok]
            if len(rejected) >= self.reacquire_after:
                if self._reacquire(m):
                    return GateDecision(False, residual, gate_m, "gate_reacquire")
                self.reacquire_refused += 1
            return GateDecision(False, residual, gate_m, "gate")
        self._window.append((m, False))
        self._nis.append(self.last_nis)
        if len(self._nis) == self._nis.maxlen and sum(self._nis) > self._nis_limit:
            # Accepted, but the recent ranges together say the covariance claims too
            # much (a drifting estimate whose current prior was too small): test for a
            # re-acquisition as after a run of rejections.
            self._nis.clear()
            if self._reacquire(m, min_rejected=0):
                return GateDecision(False, residual, gate_m, "gate_reacquire")
            self.reacquire_refused += 1
        if residual > _HUBER_K * math.sqrt(S):
            # A long reply inside the gate may still be multipath: the gate is wide when
            # the estimate is uncertain.  Weigh it as a Huber M-estimator does, so its
            # pull is that of a k-sigma residual (and its information less): a long
            # outlier cannot drag the estimate, a true range still moves it.
            r_var = residual * math.sqrt(S) / _HUBER_K - (S - r_var)
        K, self.P, _ = joseph_update(self.P, H, r_var)
        self._apply(K * residual, m.vehicle_hd)
        self._limit_current()
        self._recent.append((True, residual))
        self.history.correct(self.x.copy(), self.P.copy())
        return GateDecision(True, residual, gate_m, "ok")

    def _rays(self) -> list[reacquire.Ray]:
        """The recent ranges seen from the present estimate, for the re-acquisition fit."""
        lat, lon = float(self.x[0]), float(self.x[1])
        rays = []
        for m, rejected in self._window:
            b_lat, b_lon = m.beacon_lat, m.beacon_lon
            sigma2 = m.std_m**2 + m.beacon_position_std_m**2
            if m.beacon == self.primary:
                b_lat, b_lon = geodesy.offset_position(
                    b_lat, b_lon, float(self.x[6]), float(self.x[7]), m.beacon_hd
                )
            e, n, _ = geodesy.enu_offset(lat, lon, m.vehicle_hd, b_lat, b_lon, m.vehicle_hd)
            dn_p, de_p = self._displacement_since(m.t_ping)
            dn_b, de_b = self._displacement_since(m.t)
            rays.append(
                reacquire.Ray(
                    (n, e, m.beacon_hd - m.vehicle_hd),
                    (-dn_p, -de_p),
                    (-dn_b, -de_b),
                    max(0.0, self.t - m.t_ping),
                    max(0.0, self.t - m.t),
                    m.range_m,
                    math.sqrt(sigma2),
                    rejected,
                )
            )
        return rays

    def _reacquire(self, m: RangeMeas, min_rejected: int | None = None) -> bool:
        """Move to the correction the recent ranges agree on; False if they do not agree.

        Consecutive rejections mean either the estimate has gone wrong (the seed's
        Chesapeake run: current prior too small, every range rejected) or the ranges
        have (a multipath burst).  Only the first gives ranges that agree with one
        another on a correction.
        """
        hyp = reacquire.find(
            self._rays(),
            (float(self.x[2]), float(self.x[3])),
            self.P[:2, :2].copy(),
            self.P[2:4, 2:4].copy(),
            # a drift older than the window would have shown in the ranges before it,
            # which the covariance already holds
            min(max(0.0, self.t - self.t_anchor), _WINDOW_S),
            self.max_current,
            _MIN_SUPPORT,
            self.reacquire_after if min_rejected is None else min_rejected,
            _REACQUIRED_STD_M,
            seed=self.reacquisitions * 7919 + self.reacquire_refused,
        )
        if hyp is None:
            return False
        dx = np.zeros(N_STATES)
        dx[:4] = (hyp.d_north, hyp.d_east, hyp.dc_north, hyp.dc_east)
        self._apply(dx, m.vehicle_hd)
        # the fit is now what is known of position and current; their correlation with
        # the other states (bias, scale, beacon offset) came from the estimate it replaced
        P = self.P.copy()
        P[:4, :] = 0.0
        P[:, :4] = 0.0
        P[:4, :4] = hyp.cov
        self.P = 0.5 * (P + P.T)
        self._limit_current()
        self._recent.clear()
        self._nis.clear()
        self._window.clear()
        self.t_anchor = m.t
        self.reacquisitions += 1
        self.history.correct(self.x.copy(), self.P.copy())
        return True

    def _limit_current(self) -> None:
        """Hold the current to what water can do at this site (``max_current_mps``)."""
        speed = math.hypot(float(self.x[2]), float(self.x[3]))
        if speed > self.max_current:
            self.x[2:4] *= self.max_current / speed

    def _apply(self, dx: np.ndarray, hd: float) -> None:
        self.x = self.state_apply(self.x, dx, hd)

    # -- outputs and smoother hooks ----------------------------------------------------
    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate:
        return StateEstimate(
            float(x[0]),
            float(x[1]),
            float(x[2]),
            float(x[3]),
            float(P[0, 0]),
            float(P[1, 1]),
            float(P[0, 1]),
        )

    def estimate(self) -> StateEstimate:
        return self.estimate_of(self.x, self.P)

    def apply_fix(self, fix: Fix) -> None:
        """Ranges reach this mode one by one; the net's fix only starts it without GPS."""

    def corrections(self) -> Corrections | None:
        x = self.x
        return Corrections(float(x[4]), float(x[5]), float(x[6]), float(x[7]))

    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e, n, _ = geodesy.enu_offset(b[0], b[1], 0.0, a[0], a[1], 0.0)
        d = a - b
        d[0], d[1] = n, e
        return d

    def state_apply(self, x: np.ndarray, dx: np.ndarray, hd: float = 0.0) -> np.ndarray:
        y = x + dx
        y[0], y[1] = geodesy.offset_position(float(x[0]), float(x[1]), dx[0], dx[1], hd)
        return y
