"""Static position fix from simultaneous ranges: iterative weighted least squares.

Techy et al. (seed 004, section III): given an initial guess, the position
correction is ``theta = (H^T V^-1 H)^-1 H^T V^-1 r`` with ``H`` the Jacobian of the
range equations, ``V`` the range covariance and ``r`` the range residuals, repeated
until the correction vanishes; ``(H^T V^-1 H)^-1`` is the fix's covariance.  Depth
is measured, so the unknowns are north and east; ranges are slant ranges in 3-D.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from navd import geodesy

_MAX_ITER = 20
_CONVERGED_M = 1e-3


@dataclass(frozen=True, slots=True)
class RangeTo:
    lat: float  # beacon, radians
    lon: float
    hd: float  # beacon height minus depth
    range_m: float
    std_m: float


@dataclass(frozen=True, slots=True)
class Fix:
    lat: float  # radians
    lon: float
    cov_ne: np.ndarray  # 2 x 2, m^2
    iterations: int
    residual_rms_m: float


def least_squares_fix(
    ranges: Sequence[RangeTo],
    vehicle_hd: float,
    guess: tuple[float, float] | None = None,
    max_gdop: float = 20.0,
) -> Fix | None:
    """The fix, or None with fewer than three ranges, a degenerate geometry or no convergence."""
    if len(ranges) < 3:
        return None
    if guess is None:  # the beacons' centroid (a small area: the mean of angles is fine)
        guess = (
            sum(r.lat for r in ranges) / len(ranges),
            sum(r.lon for r in ranges) / len(ranges),
        )
    lat, lon = guess
    w = np.array([1.0 / r.std_m**2 for r in ranges])
    for it in range(1, _MAX_ITER + 1):
        H = np.empty((len(ranges), 2))
        res = np.empty(len(ranges))
        for i, r in enumerate(ranges):
            pred, dn, de = geodesy.range_and_gradient(lat, lon, vehicle_hd, r.lat, r.lon, r.hd)
            H[i] = (dn, de)
            res[i] = r.range_m - pred
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(res))):
            return None
        N = H.T @ (w[:, None] * H)
        # Collinear beacons (or the vehicle on their baseline) make N singular; round-off
        # can then leave it with a zero or negative eigenvalue and its inverse with a
        # negative trace.  Either is a geometry with no fix, not an error.
        eig = np.linalg.eigvalsh(N)
        if not (np.all(np.isfinite(eig)) and eig[0] > 1e-12 * max(eig[-1], 1e-300)):
            return None
        cov = np.linalg.inv(N)
        # geometry too poor: the fix would be mostly noise (GDOP in units of range sigma)
        gdop2 = float(np.trace(cov)) * float(w.mean())
        if not (math.isfinite(gdop2) and 0.0 < gdop2 <= max_gdop * max_gdop):
            return None
        theta = cov @ H.T @ (w * res)
        lat, lon = geodesy.offset_position(lat, lon, float(theta[0]), float(theta[1]), vehicle_hd)
        if math.hypot(*theta) < _CONVERGED_M:
            rms = float(np.sqrt(np.mean(res**2)))
            return Fix(lat, lon, cov, it, rms)
    return None
