"""The recent ranges linearised again where the later ones put the vehicle: an iterated
Kalman smoother over a sliding window (Bell 1994, "The iterated Kalman smoother as a
Gauss-Newton method", SIAM J. Optim. 4(3)).

Why: a single beacon's range says nothing across its line of sight, and an EKF takes
each range's direction (its Jacobian) from the estimate at that moment.  An estimate
off across the line turns the range's correction the wrong way, and the current and
calibration states take up the misdirected part for good (BENCHMARKS.md: the distance
from the bound is the filter's own, not the outliers').  Later ranges, from other
bearings as vehicle and boat move, say where the vehicle was; linearising each range of
the window there again, and solving the window as one least-squares problem, corrects
the directions the filter used.

The window is the filter's own chain over its last accepted ranges, kept as it ran
(:class:`Step`): each range's prior and posterior, the motion between them as a
transition ``phi`` and process noise ``qd`` in the error state, and the range's
geometry.  Every pass runs the Kalman filter over the window with the ranges linearised
at the last pass's smoothed states, then the Rauch-Tung-Striebel smoother back, until
the states stop moving.  The new estimate is the last forward pass's end: the filter
as it would have run had it known where to linearise.

Sans I/O and total: the range model comes in as a function of the error state about
each step's prior, and anything not finite leaves the filter's own estimate (``None``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from navd.filter.ekf_core import N_STATES

#: (error state about a step's prior, its geometry) -> (predicted range m, Jacobian)
RangeModel = Callable[[np.ndarray, Any], tuple[float, np.ndarray]]


class LineOfSight(NamedTuple):
    """A range's round trip as the filter fused it: each leg's length and unit line of
    sight (beacon to vehicle, north and east parts) at the prior, and how long before
    the update each end was."""

    r_ping: float
    n_ping: float
    e_ping: float
    r_reply: float
    n_reply: float
    e_reply: float
    lag_ping: float
    lag_reply: float
    tracked: bool  # the beacon whose reported-position error the state holds (o_n, o_e)


def window_range(d: np.ndarray, g: LineOfSight) -> tuple[float, np.ndarray]:
    """The default mode's round trip (navd/filter/ekf_ranges.py): its range and Jacobian
    from the state ``d``, the error state about the prior it was fused at.

    Each leg is moved in the plane of the prior's north and east: for the window's moves
    of a few hundred metres the plane's range is the geodesic one within a millimetre
    (tests/test_relinearise.py), and it costs no geodesic in the window's passes.  At
    ``d = 0`` it is the exact range and Jacobian the filter used.
    """
    dn, de = float(d[0]), float(d[1])
    if g.tracked:
        # moving the beacon moves the range like moving the vehicle the other way
        dn -= float(d[6])
        de -= float(d[7])
    dcn, dce = float(d[2]), float(d[3])
    r = 0.0
    H = np.zeros(N_STATES)
    for length, un, ue, lag in (
        (g.r_ping, g.n_ping, g.e_ping, g.lag_ping),
        (g.r_reply, g.n_reply, g.e_reply, g.lag_reply),
    ):
        # the end moves with the position, and by the current's change over its lag
        vn = length * un + dn - dcn * lag
        ve = length * ue + de - dce * lag
        vz2 = max(0.0, length * length * (1.0 - un * un - ue * ue))
        leg = math.sqrt(vn * vn + ve * ve + vz2)
        r += 0.5 * leg
        if leg > 0.0:
            H[0] += 0.5 * vn / leg
            H[1] += 0.5 * ve / leg
            H[2] -= 0.5 * lag * vn / leg
            H[3] -= 0.5 * lag * ve / leg
    if g.tracked:
        H[6] = -H[0]
        H[7] = -H[1]
    return r, H


@dataclass(slots=True)
class Step:
    """One accepted range of the window, as the filter fused it.  Error states are
    about this step's prior."""

    t: float
    P_prior: np.ndarray
    k: np.ndarray  # the filter's correction: its posterior about its prior
    P_post: np.ndarray
    phi: np.ndarray  # the error state's transition from the previous step's posterior
    qd: np.ndarray  # and the process noise it gathered on the way
    geometry: Any  # what the range model needs besides the state
    range_m: float
    r_var: float  # the variance the filter gave it (Huber-widened where it read long)
    x_prior: np.ndarray  # the filter's own nominal states, which the caller keeps
    x_post: np.ndarray


def transition_noise(phi: np.ndarray, P_post_prev: np.ndarray, P_prior: np.ndarray) -> np.ndarray:
    """The process noise between two steps: what the prior holds beyond the propagated
    posterior (the filter's prediction is linear in the error state)."""
    q: np.ndarray = P_prior - phi @ P_post_prev @ phi.T
    q += q.T
    q *= 0.5
    return q


def _load_compiled() -> tuple[Callable[..., int | None], int] | None:
    if os.environ.get("NAVD_PURE_PYTHON"):
        return None
    try:
        from navd.filter import _window
    except ImportError:
        return None  # built without a C compiler: the reference solves every window
    fn: Callable[..., int | None] = _window.solve
    return fn, int(_window.MAX_STEPS)


_loaded = _load_compiled()
_compiled, _MAX_COMPILED_STEPS = _loaded if _loaded is not None else (None, 0)
#: whether the compiled solve is in use (says so in the replay's speed bench)
COMPILED = _compiled is not None


def solve(
    steps: Sequence[Step], max_passes: int, tol_m: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`smooth` with the default mode's range model (:func:`window_range`), compiled
    where it can be (navd/filter/_window.c, the same arithmetic; tests/test_relinearise.py
    holds the two together)."""
    n = len(steps)
    if _compiled is None or not 2 <= n <= _MAX_COMPILED_STEPS:
        return smooth(steps, window_range, max_passes, tol_m)
    d = np.empty(N_STATES)
    P = np.empty((N_STATES, N_STATES))
    passes = _compiled(
        n,
        np.ascontiguousarray(steps[0].P_prior, dtype=float),
        np.array([s.k for s in steps], dtype=float),
        np.array([s.phi for s in steps], dtype=float),
        np.array([s.qd for s in steps], dtype=float),
        np.array([s.geometry for s in steps], dtype=float),
        np.array([s.range_m for s in steps], dtype=float),
        np.array([s.r_var for s in steps], dtype=float),
        np.array([s.k for s in steps], dtype=float),  # the passes start where the filter ended
        max_passes,
        tol_m,
        d,
        P,
    )
    return None if passes is None else (d, P)


def smooth(
    steps: Sequence[Step], model: RangeModel, max_passes: int, tol_m: float
) -> tuple[np.ndarray, np.ndarray] | None:
    """The last step's correction about its prior and its covariance, with every range
    of the window relinearised; ``None`` when the window says nothing new or breaks
    down."""
    if len(steps) < 2:
        return None
    with np.errstate(all="ignore"):
        return _solve(steps, model, max_passes, tol_m)


def _solve(
    steps: Sequence[Step], model: RangeModel, max_passes: int, tol_m: float
) -> tuple[np.ndarray, np.ndarray] | None:
    k = [s.k for s in steps]
    # linearisation points: start where the filter ended each step
    lin = list(k)
    result: tuple[np.ndarray, np.ndarray] | None = None
    for _ in range(max_passes):
        fwd = _forward(steps, lin, model)
        if fwd is None:
            return None
        d_prior, P_prior, d_post, P_post = fwd
        result = d_post[-1], P_post[-1]
        smoothed = _backward(steps, d_prior, P_prior, d_post, P_post)
        if smoothed is None:
            return None
        moved = max(
            float(np.hypot(a[0] - b[0], a[1] - b[1])) for a, b in zip(smoothed, lin, strict=True)
        )
        lin = smoothed
        if not moved >= tol_m:
            break
    if result is None:
        return None
    d, P = result
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(P))):
        return None
    return d, P


def _forward(
    steps: Sequence[Step], lin: list[np.ndarray], model: RangeModel
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]] | None:
    d_prior: list[np.ndarray] = []
    P_prior: list[np.ndarray] = []
    d_post: list[np.ndarray] = []
    P_post: list[np.ndarray] = []
    d = np.zeros(len(lin[0]))
    P = steps[0].P_prior
    eye = np.eye(len(d))
    prev: Step | None = None
    for j, s in enumerate(steps):
        if prev is not None:
            # the filter moved on from its posterior, prev.k about its prior: the state
            # about this step's prior is the propagated difference
            d = s.phi @ (d - prev.k)
            P = s.phi @ P @ s.phi.T + s.qd
        prev = s
        d_prior.append(d)
        P_prior.append(P)
        r, H = model(lin[j], s.geometry)
        nu = s.range_m - r - float(H @ (d - lin[j]))
        PH = P @ H
        S = float(H @ PH) + s.r_var
        if not (S > 0.0):
            return None
        K = PH / S
        d = d + K * nu
        IKH = eye - np.outer(K, H)
        P = IKH @ P @ IKH.T + s.r_var * np.outer(K, K)
        P = 0.5 * (P + P.T)
        d_post.append(d)
        P_post.append(P)
    return d_prior, P_prior, d_post, P_post


def _backward(
    steps: Sequence[Step],
    d_prior: list[np.ndarray],
    P_prior: list[np.ndarray],
    d_post: list[np.ndarray],
    P_post: list[np.ndarray],
) -> list[np.ndarray] | None:
    n = len(steps)
    out = [d_post[-1]]
    for j in range(n - 2, -1, -1):
        phi = steps[j + 1].phi
        try:
            # G = P_j+ phi^T (P_j+1-)^-1, from the symmetric solve
            G = np.linalg.solve(P_prior[j + 1], phi @ P_post[j]).T
        except np.linalg.LinAlgError:
            return None
        out.append(d_post[j] + G @ (out[-1] - d_prior[j + 1]))
    out.reverse()
    if not all(np.all(np.isfinite(v)) for v in out):
        return None
    return out
