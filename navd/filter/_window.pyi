# The compiled window solve (navd/filter/_window.c); navd/filter/relinearise.py says what it does.
import numpy as np

MAX_STEPS: int

def solve(
    n: int,
    P0: np.ndarray,
    k: np.ndarray,
    phi: np.ndarray,
    qd: np.ndarray,
    geometry: np.ndarray,
    z: np.ndarray,
    r_var: np.ndarray,
    lin: np.ndarray,
    max_passes: int,
    tol: float,
    d: np.ndarray,
    P: np.ndarray,
    /,
) -> int | None: ...
