"""The ``thesis`` mode: Jabari 2016's geodetic range EKF exactly as published (seed 000).

State x = (phi, lambda, v_phi, v_lambda) in radians and radians per second.
Kinematic model eq. 3.10 (great-circle step eq. 2.5 on a sphere of radius eq. 3.9,
plus the current), measurement eq. 3.13, Jacobians of Appendix B, accept/reject of
Algorithm 1 with the radius of error eq. 3.14-3.16, EKF loop of Algorithm 2, GPS
(re)initialisation at the surface, covariances given in metres and converted with
eq. 4.1.  It is the yardstick, so its weaknesses are kept: a one-sigma gate that can
lock the filter out for good, the range taken as if it belonged to the arrival time,
no sound-speed correction, the plain (I - KH) P update.
"""

from __future__ import annotations

import math

import numpy as np

from navd import geodesy
from navd.filter.common import (
    Corrections,
    GateDecision,
    Held,
    History,
    RangeMeas,
    StateEstimate,
)
from navd.filter.lsfix import Fix


def metres_to_rad2(lat: float, var_n_m2: float, var_e_m2: float) -> tuple[float, float]:
    """Variances in metres^2 to radians^2 of latitude and longitude (eq. 4.1)."""
    m_lat, m_lon = geodesy.metres_per_degree(lat)
    k = (math.pi / 180.0) ** 2
    return var_n_m2 / m_lat**2 * k, var_e_m2 / m_lon**2 * k


def rad_to_metres_scale(lat: float) -> tuple[float, float]:
    """Metres per radian of latitude and longitude (eq. 3.16 without the squares)."""
    m_lat, m_lon = geodesy.metres_per_degree(lat)
    return 180.0 / math.pi * m_lat, 180.0 / math.pi * m_lon


def kinematic_model(
    x: np.ndarray, dt: float, heading: float, speed: float, radius: float
) -> np.ndarray:
    """f(x[k-1], k) of eq. 3.10."""
    phi, lam, vphi, vlam = x
    xi = dt * speed / radius
    sphi, cphi = math.sin(phi), math.cos(phi)
    a = math.cos(xi) * sphi + cphi * math.cos(heading) * math.sin(xi)
    f1 = math.asin(max(-1.0, min(1.0, a))) + dt * vphi
    chi = cphi * math.sin(heading) * math.sin(xi)
    omega = math.cos(xi) - math.sin(f1) * sphi
    f2 = lam + math.atan2(chi, omega) + dt * vlam
    return np.array([f1, geodesy.wrap_lon(f2), vphi, vlam])


def kinematic_jacobian(
    x: np.ndarray, dt: float, heading: float, speed: float, radius: float
) -> np.ndarray:
    """F of Appendix B, with the per-step radius held constant as the thesis does."""
    phi, _, vphi, _ = x
    xi = dt * speed / radius
    sphi, cphi = math.sin(phi), math.cos(phi)
    cxi, sxi = math.cos(xi), math.sin(xi)
    sh, ch = math.sin(heading), math.cos(heading)
    a = cxi * sphi + cphi * ch * sxi
    df1_dphi = (cxi * cphi - sphi * ch * sxi) / math.sqrt(max(1e-300, 1.0 - a * a))
    f1 = math.asin(max(-1.0, min(1.0, a))) + dt * vphi
    sf1, cf1 = math.sin(f1), math.cos(f1)
    y = cphi * sh * sxi
    xx = cxi - sf1 * sphi
    d2 = xx * xx + y * y
    dy_dphi = -sphi * sh * sxi
    dx_dphi = -cf1 * df1_dphi * sphi - sf1 * cphi
    dx_dvphi = -cf1 * dt * sphi
    F = np.eye(4)
    F[0, 0] = df1_dphi
    F[0, 2] = dt
    F[1, 0] = (xx * dy_dphi - y * dx_dphi) / d2
    F[1, 2] = -y * dx_dvphi / d2
    F[1, 3] = dt
    return F


def measurement_model(
    x: np.ndarray, hd: float, lat_t: float, lon_t: float, hd_t: float
) -> tuple[float, np.ndarray]:
    """h(x) of eq. 3.13 and its Jacobian H (Appendix B), per radian."""
    phi, lam = float(x[0]), float(x[1])
    r, dn, de = geodesy.range_and_gradient(phi, lam, hd, lat_t, lon_t, hd_t)
    m = geodesy.meridian_radius(phi) + hd
    n = (geodesy.prime_vertical_radius(phi) + hd) * math.cos(phi)
    return r, np.array([dn * m, de * n, 0.0, 0.0])


def radius_of_error(P: np.ndarray, lat: float, range_var_m2: float) -> float:
    """r_e of eq. 3.14 with P_11, P_22 converted to metres by eq. 3.16."""
    sn, se = rad_to_metres_scale(lat)
    return math.sqrt(P[0, 0] * sn * sn + P[1, 1] * se * se + range_var_m2)


def accept_or_reject(expected_m: float, measured_m: float, r_e: float) -> bool:
    """Algorithm 1."""
    return abs(expected_m - measured_m) <= r_e


class ThesisEKF:
    """Algorithm 2 of seed 000."""

    ranges_as_reported = True  # the thesis ranges with the modem's own sound speed
    ranges_only_without_gps = True  # Algorithm 2 line 13
    last_nis = math.nan  # Algorithm 1 gates on the residual alone
    last_pull = math.nan

    def __init__(
        self,
        position_init_std_m: float,
        current_init_std_mps: float,
        position_walk_m_per_sqrt_s: float,
        current_walk_mps_per_sqrt_s: float,
    ) -> None:
        self.pos_std = position_init_std_m
        self.cur_std = current_init_std_mps
        self.q_pos = position_walk_m_per_sqrt_s
        self.q_cur = current_walk_mps_per_sqrt_s
        self.x = np.zeros(4)
        self.P = np.eye(4)
        self.initialised = False
        self.history = History()

    def keep_history(self) -> None:
        self.history.enabled = True

    def close_history(self) -> None:
        self.history.close()

    def apply_fix(self, fix: Fix) -> None:
        """The thesis uses no acoustic fix."""

    def corrections(self) -> Corrections | None:
        return None

    def _metres_cov(self, lat: float, pos_var: float, cur_var: float) -> np.ndarray:
        pn, pe = metres_to_rad2(lat, pos_var, pos_var)
        cn, ce = metres_to_rad2(lat, cur_var, cur_var)
        return np.diag([pn, pe, cn, ce])

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        # Algorithm 2 lines 2-11: currents start at zero, P from the metre variances.
        self.x = np.array([lat, lon, 0.0, 0.0])
        self.P = self._metres_cov(lat, self.pos_std**2, self.cur_std**2)
        self.initialised = True
        self.history.add(t, np.eye(4), self.x.copy(), self.P.copy())

    def checkpoint(self) -> tuple[np.ndarray, np.ndarray, Held]:
        return self.x.copy(), self.P.copy(), Held()

    def restore(
        self, x: np.ndarray, P: np.ndarray, grow_m2: float, held: Held | None = None
    ) -> None:
        # the thesis' covariance is in radians squared: the growth is converted there
        self.x, self.P = x.copy(), P.copy()
        pn, pe = metres_to_rad2(float(x[0]), grow_m2, grow_m2)
        self.P[0, 0] += pn
        self.P[1, 1] += pe
        self.history.correct(self.x.copy(), self.P.copy())

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None:
        # Algorithm 2 line 14: "return position of AUV and update P".
        self.x[0], self.x[1] = lat, lon
        pn, pe = metres_to_rad2(lat, self.pos_std**2, self.pos_std**2)
        self.P[0, :] = 0.0
        self.P[:, 0] = 0.0
        self.P[1, :] = 0.0
        self.P[:, 1] = 0.0
        self.P[0, 0], self.P[1, 1] = pn, pe
        self.history.correct(self.x.copy(), self.P.copy())

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        radius = geodesy.centre_distance(self.x[0], self.x[1], hd)
        F = kinematic_jacobian(self.x, dt, heading, speed, radius)
        self.x = kinematic_model(self.x, dt, heading, speed, radius)
        Q = self._metres_cov(self.x[0], self.q_pos**2 * dt, self.q_cur**2 * dt)
        self.P = F @ self.P @ F.T + Q
        if self.history.enabled:
            self.history.add(t, F, self.x.copy(), self.P.copy())

    def range_update(self, m: RangeMeas) -> GateDecision:
        # The thesis takes the range as belonging to the arrival time.
        expected, H = measurement_model(
            self.x, m.vehicle_hd, m.beacon_lat, m.beacon_lon, m.beacon_hd
        )
        r_var = m.std_m**2
        r_e = radius_of_error(self.P, self.x[0], r_var)
        residual = m.range_m - expected
        if not accept_or_reject(expected, m.range_m, r_e):
            return GateDecision(False, residual, r_e, "gate", on_residual=True)
        S = float(H @ self.P @ H) + r_var
        K = self.P @ H / S
        self.x = self.x + K * residual
        self.x[1] = geodesy.wrap_lon(self.x[1])
        self.P = (np.eye(4) - np.outer(K, H)) @ self.P
        self.history.correct(self.x.copy(), self.P.copy())
        return GateDecision(True, residual, r_e, "ok")

    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate:
        sn, se = rad_to_metres_scale(float(x[0]))
        return StateEstimate(
            float(x[0]),
            float(x[1]),
            float(x[2]) * sn,
            float(x[3]) * se,
            float(P[0, 0]) * sn * sn,
            float(P[1, 1]) * se * se,
            float(P[0, 1]) * sn * se,
        )

    def estimate(self) -> StateEstimate:
        return self.estimate_of(self.x, self.P)

    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d: np.ndarray = a - b
        d[1] = geodesy.wrap_lon(d[1])
        return d

    def state_apply(self, x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        y: np.ndarray = x + dx
        y[1] = geodesy.wrap_lon(y[1])
        return y
