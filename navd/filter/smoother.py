"""Rauch-Tung-Striebel fixed-interval smoother over a filter's step history.

Techy et al. (seed 004) smooth their LBL EKF with RTS; the equations are the
standard ones (Rauch, Tung & Striebel, AIAA J. 3(8), 1965; Simon, *Optimal State
Estimation*, 2006, sec. 9.4.2):

    C_k   = P_k|k F_k+1^T P_k+1|k^-1
    x_k|N = x_k|k + C_k (x_k+1|N - x_k+1|k)
    P_k|N = P_k|k + C_k (P_k+1|N - P_k+1|k) C_k^T

State differences and corrections go through the filter's own ``diff`` and
``apply`` so that a geodetic nominal state is smoothed in metres.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Protocol

import numpy as np

from navd.filter.common import Step


class Steps(Protocol):
    """A filter's steps in time order (a list, or :class:`navd.filter.common.History`)."""

    def __len__(self) -> int: ...

    def __getitem__(self, k: int) -> Step: ...


def rts_backward(
    steps: Steps,
    diff: Callable[[np.ndarray, np.ndarray], np.ndarray],
    apply: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """The smoothed state and covariance of every step, ``(k, x, P)``, from the last
    step back to the first: each needs only the one after it, so nothing is held."""
    n = len(steps)
    if n == 0:
        return
    nxt = steps[n - 1]
    x_s, P_s = nxt.x_filt, nxt.P_filt
    yield n - 1, x_s, P_s
    for k in range(n - 2, -1, -1):
        cur = steps[k]
        # C = Pf F^T Pp^-1, computed as the solution of Pp C^T = F Pf (Pp symmetric).
        C = np.linalg.solve(nxt.P_pred, nxt.F @ cur.P_filt).T
        x_s = apply(cur.x_filt, C @ diff(x_s, nxt.x_pred))
        P = cur.P_filt + C @ (P_s - nxt.P_pred) @ C.T
        P_s = 0.5 * (P + P.T)
        yield k, x_s, P_s
        nxt = cur
