# The compiled step (navd/filter/_ekf_step.c); navd/filter/ekf_step.py says what it does.
import numpy as np

def predict(
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
    noise: tuple[float, float, float, float, float, float],
    geodesic: tuple[float, float, float],
    /,
) -> tuple[float, float, float, float, float] | None: ...
