"""The ``vlbl`` mode: virtual LBL as the navigation solution (LaPointe 2006, seed 001).

Between fixes the position is dead-reckoned (compass, RPM speed, no current) and
its uncertainty grows; each range goes to the virtual net (navd/filter/vlbl.py), and when
the net yields a fix the position and covariance are the fix's.  It is what
seed 001 flies, selectable so that it can be compared with the range EKF on the
same logs.  Its fixes replace the state rather than update it, so it has nothing
for the RTS smoother (it is no :class:`~navd.filter.common.Smoothable`).
"""

from __future__ import annotations

import math

import numpy as np

from navd import geodesy
from navd.filter.common import Corrections, GateDecision, Held, RangeMeas, StateEstimate
from navd.filter.lsfix import Fix


class VlblMode:
    ranges_as_reported = False
    ranges_only_without_gps = False
    last_nis = math.nan  # ranges act through the net's fixes, not a gate
    last_pull = math.nan

    def __init__(self, drift_mps: float = 0.1) -> None:
        self.drift = drift_mps  # position uncertainty growth between fixes
        self.x = np.zeros(2)
        self.P = np.eye(2)
        self.initialised = False
        self.t = 0.0

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        self.x = np.array([lat, lon])
        self.P = np.eye(2) * std_m**2
        self.initialised = True
        self.t = t

    def checkpoint(self) -> tuple[np.ndarray, np.ndarray, Held]:
        return self.x.copy(), self.P.copy(), Held()

    def restore(
        self, x: np.ndarray, P: np.ndarray, grow_m2: float, held: Held | None = None
    ) -> None:
        self.x, self.P = x.copy(), P + np.eye(2) * grow_m2

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None:
        self.x = np.array([lat, lon])
        self.P = np.eye(2) * std_m**2

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        d = speed * dt
        if d:
            lat, lon, _ = geodesy.destination(self.x[0], self.x[1], heading, d, hd)
            self.x = np.array([lat, lon])
        self.P = self.P + np.eye(2) * self.drift**2 * dt
        self.t = t

    def range_update(self, m: RangeMeas) -> GateDecision:
        # ranges act through the net's fixes (apply_fix); report the range's residual
        pred = geodesy.ecef_distance(
            self.x[0], self.x[1], m.vehicle_hd, m.beacon_lat, m.beacon_lon, m.beacon_hd
        )
        return GateDecision(True, m.range_m - pred, math.inf, "to_net")

    def apply_fix(self, fix: Fix) -> None:
        self.x = np.array([fix.lat, fix.lon])
        self.P = np.array(fix.cov_ne, dtype=float)

    def corrections(self) -> Corrections | None:
        return None

    def estimate(self) -> StateEstimate:
        x, P = self.x, self.P
        return StateEstimate(
            float(x[0]), float(x[1]), 0.0, 0.0, float(P[0, 0]), float(P[1, 1]), float(P[0, 1])
        )
