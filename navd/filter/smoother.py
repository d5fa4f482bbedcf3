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

from collections.abc import Callable, Sequence

import numpy as np

from navd.filter.common import Step


def rts_smooth(
    steps: Sequence[Step],
    diff: Callable[[object, object], np.ndarray],
    apply: Callable[[object, np.ndarray], object],
) -> tuple[list[object], list[np.ndarray]]:
    n = len(steps)
    xs: list[object] = [None] * n
    Ps: list[np.ndarray] = [np.empty(0)] * n
    xs[-1], Ps[-1] = steps[-1].x_filt, steps[-1].P_filt
    for k in range(n - 2, -1, -1):
        cur, nxt = steps[k], steps[k + 1]
        # C = Pf F^T Pp^-1, computed as the solution of Pp C^T = F Pf (Pp symmetric).
        C = np.linalg.solve(nxt.P_pred, nxt.F @ cur.P_filt).T
        xs[k] = apply(cur.x_filt, C @ diff(xs[k + 1], nxt.x_pred))
        P = cur.P_filt + C @ (Ps[k + 1] - nxt.P_pred) @ C.T
        Ps[k] = 0.5 * (P + P.T)
    return xs, Ps
