"""The default mode's prediction step (navd/filter/ekf.py) as one function over its
arrays: the nominal state moved along the geodesic, the transition F and process noise
Q filled in, and the covariance propagated, all in place.

``predict_step`` is the reference.  Where a C compiler was at hand when navd was
installed, ``navd.filter._ekf_step`` does the same arithmetic compiled (a replay
takes this step twice a tick, and in numpy its 8x8 products cost more in calls than
in arithmetic); it takes only the ordinary step, a move short enough for one midpoint
step of navd.geodesy.destination with finite inputs, and hands anything else back to
the reference.  ``NAVD_PURE_PYTHON=1`` in the environment keeps the compiled step out
(to compare the two, or to rule it out).
Compiled, a step differs from the reference in the last bits of the covariance (its
sums run in another order): tests/test_ekf_step.py holds the two together.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable

import numpy as np

from navd import geodesy

#: (speed std m/s, heading std rad, input correlation s, current walk m/s/sqrt(s),
#: heading-bias walk rad/sqrt(s), speed-scale walk /sqrt(s))
Noise = tuple[float, float, float, float, float, float]
#: what a step gives back for the filter's own books: (dn, de) metres moved, the
#: surge speed u and the cosine and sine of the corrected heading
Moved = tuple[float, float, float, float, float]

#: what the compiled step needs of navd.geodesy: the ellipsoid (a, e^2) and the longest
#: move destination() takes in one midpoint step
_GEODESIC = (geodesy.WGS84.a, geodesy.WGS84.e2, geodesy.MIDPOINT_MAX_M)


def predict_step(
    x: np.ndarray,
    P: np.ndarray,
    F: np.ndarray,
    Q: np.ndarray,
    dt: float,
    heading: float,
    speed: float,
    hd: float,
    phi: float,
    q_off: float,
    noise: Noise,
) -> Moved:
    """Propagate ``x`` and ``P`` over ``dt`` in place (``F`` and ``Q`` are filled as
    scratch, and kept for the smoother); ``phi`` and ``q_off`` are the beacon offsets'
    decay and its process noise over the step."""
    lat, lon, cn, ce, b, s = x[:6].tolist()
    psi = heading + b
    u = s * speed
    cpsi, spsi = math.cos(psi), math.sin(psi)
    vn = u * cpsi + cn
    ve = u * spsi + ce
    dn, de = vn * dt, ve * dt
    x[0], x[1] = geodesy.offset_position(lat, lon, dn, de, hd)

    # F is the identity but for the position rows and the offsets' decay; Q diagonal
    # but for the along/cross-track position block
    F[0, 2] = dt
    F[1, 3] = dt
    F[0, 4] = -u * spsi * dt
    F[1, 4] = u * cpsi * dt
    F[0, 5] = speed * cpsi * dt
    F[1, 5] = speed * spsi * dt
    F[6, 6] = F[7, 7] = phi
    x[6] *= phi
    x[7] *= phi

    speed_std, heading_std, tau, cur_walk, bias_walk, scale_walk = noise
    # Heading and speed errors are correlated over tau, so their effect on position
    # grows like a random walk with that time constant (first-order Gauss-Markov, short
    # correlation): q = sigma^2 * tau per second.
    var_along = (speed_std**2) * tau * dt
    var_cross = (u * heading_std) ** 2 * tau * dt
    Q[0, 0] = var_along * cpsi * cpsi + var_cross * spsi * spsi
    Q[1, 1] = var_along * spsi * spsi + var_cross * cpsi * cpsi
    Q[0, 1] = Q[1, 0] = (var_along - var_cross) * cpsi * spsi
    Q[2, 2] = Q[3, 3] = cur_walk**2 * dt
    Q[4, 4] = bias_walk**2 * dt
    Q[5, 5] = scale_walk**2 * dt
    Q[6, 6] = Q[7, 7] = q_off

    M = F @ P @ F.T
    M += M.T  # symmetric by construction; this removes the round-off
    M *= 0.5
    M += Q
    P[...] = M
    return dn, de, u, cpsi, spsi


_Compiled = Callable[
    [np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float, float, float, float, float,
     Noise, tuple[float, float, float]],
    Moved | None,
]


def _load_compiled() -> _Compiled | None:
    if os.environ.get("NAVD_PURE_PYTHON"):
        return None
    try:
        from navd.filter._ekf_step import predict as compiled
    except ImportError:
        return None  # built without a C compiler: the reference does every step
    fn: _Compiled = compiled
    return fn


_compiled = _load_compiled()
#: whether the compiled step is in use (says so in the replay's speed bench)
COMPILED = _compiled is not None


def step(
    x: np.ndarray,
    P: np.ndarray,
    F: np.ndarray,
    Q: np.ndarray,
    dt: float,
    heading: float,
    speed: float,
    hd: float,
    phi: float,
    q_off: float,
    noise: Noise,
) -> Moved:
    """:func:`predict_step`, compiled where it can be."""
    if _compiled is not None:
        moved = _compiled(x, P, F, Q, dt, heading, speed, hd, phi, q_off, noise, _GEODESIC)
        if moved is not None:
            return moved
    return predict_step(x, P, F, Q, dt, heading, speed, hd, phi, q_off, noise)
