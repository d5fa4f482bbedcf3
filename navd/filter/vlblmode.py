"""The ``vlbl`` mode: virtual LBL as the navigation solution (LaPointe 2006, seed 001).

Between fixes the position is dead-reckoned (compass, RPM speed, no current) and
its uncertainty grows; each range goes to the virtual net (navd/filter/vlbl.py), and when
the net yields a fix the position and covariance are the fix's.  It is what
seed 001 flies, selectable so that it can be compared with the range EKF on the
same logs.
"""

from __future__ import annotations

import math

import numpy as np

from navd import geodesy
from navd.filter.common import Corrections, GateDecision, History, RangeMeas, StateEstimate
from navd.filter.lsfix import Fix


class VlblMode:
    ranges_as_reported = False
    ranges_only_without_gps = False
    last_nis = math.nan  # ranges act through the net's fixes, not a gate

    def __init__(self, drift_mps: float = 0.1) -> None:
        self.drift = drift_mps  # position uncertainty growth between fixes
        self.x = np.zeros(2)
        self.P = np.eye(2)
        self.initialised = False
        self.history = History()
        self.t = 0.0

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        self.x = np.array([lat, lon])
        self.P = np.eye(2) * std_m**2
        self.initialised = True
        self.t = t
        self.history.add(t, np.eye(2), self.x.copy(), self.P.copy())

    def restore(self, x: np.ndarray, P: np.ndarray, grow_m2: float) -> None:
        self.x, self.P = x.copy(), P + np.eye(2) * grow_m2
        self.history.correct(self.x.copy(), self.P.copy())

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None:
        self.x = np.array([lat, lon])
        self.P = np.eye(2) * std_m**2
        self.history.correct(self.x.copy(), self.P.copy())

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        d = speed * dt
        if d:
            lat, lon, _ = geodesy.destination(self.x[0], self.x[1], heading, d, hd)
            self.x = np.array([lat, lon])
        self.P = self.P + np.eye(2) * self.drift**2 * dt
        self.t = t
        self.history.add(t, np.eye(2), self.x.copy(), self.P.copy())

    def range_update(self, m: RangeMeas) -> GateDecision:
        # ranges act through the net's fixes (apply_fix); report the range's residual
        pred = geodesy.ecef_distance(
            self.x[0], self.x[1], m.vehicle_hd, m.beacon_lat, m.beacon_lon, m.beacon_hd
        )
        return GateDecision(True, m.range_m - pred, math.inf, "to_net")

    def apply_fix(self, fix: Fix) -> None:
        self.x = np.array([fix.lat, fix.lon])
        self.P = np.array(fix.cov_ne, dtype=float)
        self.history.correct(self.x.copy(), self.P.copy())

    def corrections(self) -> Corrections | None:
        return None

    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate:
        return StateEstimate(
            float(x[0]), float(x[1]), 0.0, 0.0, float(P[0, 0]), float(P[1, 1]), float(P[0, 1])
        )

    def estimate(self) -> StateEstimate:
        return self.estimate_of(self.x, self.P)

    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e, n, _ = geodesy.enu_offset(b[0], b[1], 0.0, a[0], a[1], 0.0)
        return np.array([n, e])

    def state_apply(self, x: np.ndarray, dx: np.ndarray, hd: float = 0.0) -> np.ndarray:
        return np.array(geodesy.offset_position(float(x[0]), float(x[1]), dx[0], dx[1], hd))
