"""The window's iterated smoother (navd/filter/relinearise.py): exact where the model is
linear, closer than the EKF where it is not, and total."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from navd import geodesy
from navd.filter import relinearise
from navd.filter.common import RangeMeas
from navd.filter.ekf import RangeEKF
from navd.settings import NoiseConfig

R = math.radians
LAT, LON = R(38.32), R(-76.39)


def _linear(d: np.ndarray, geometry: tuple[np.ndarray, np.ndarray]) -> tuple[float, np.ndarray]:
    """A measurement linear in the state: ``g . x``, ``x`` the step's prior plus ``d``."""
    g, x_prior = geometry
    return float(g @ (x_prior + d)), g


def _kalman_window(rng: np.random.Generator, n: int) -> tuple[list[relinearise.Step], np.ndarray]:
    """A Kalman filter over a linear model (position, velocity in 2-D), kept as a window."""
    steps: list[relinearise.Step] = []
    x = rng.normal(size=4)
    P = np.diag([25.0, 25.0, 0.1, 0.1])
    phi = np.eye(4)
    phi[0, 2] = phi[1, 3] = 10.0
    q = np.diag([1.0, 1.0, 1e-3, 1e-3])
    for j in range(n):
        if j > 0:
            x, P = phi @ x, phi @ P @ phi.T + q
        g = rng.normal(size=4)
        z = float(g @ x) + rng.normal(scale=3.0)
        x_prior, P_prior = x.copy(), P.copy()
        PH = P @ g
        S = float(g @ PH) + 9.0
        K = PH / S
        x = x + K * (z - float(g @ x))
        IKH = np.eye(4) - np.outer(K, g)
        P = IKH @ P @ IKH.T + 9.0 * np.outer(K, K)
        steps.append(
            relinearise.Step(
                10.0 * j, P_prior, x - x_prior, P.copy(), phi if j else np.eye(4),
                q if j else np.zeros((4, 4)), (g, x_prior), z, 9.0, x_prior, x.copy(),
            )
        )
    return steps, x


def test_a_linear_model_leaves_the_kalman_filter_as_it_was() -> None:
    """Linearisation points do not matter to a linear model: the smoother's forward pass
    is the filter, whatever it starts from."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        steps, x_end = _kalman_window(rng, 8)
        solved = relinearise.smooth(steps, _linear, 3, 0.01)
        assert solved is not None
        d, P = solved
        assert np.allclose(steps[-1].x_prior + d, x_end, atol=1e-9)
        assert np.allclose(P, steps[-1].P_post, atol=1e-9)


def _range_mission(seed: int, window: int) -> tuple[float, bool]:
    """A vehicle 60 m (1 sigma) from where the filter starts it, running north-east past a
    beacon 300 m away, ranged every 10 s: its position error after five minutes, and
    whether the truth is inside the 95 % ellipse."""
    rng = np.random.default_rng(seed)
    f = RangeEKF(NoiseConfig(current_init_std_mps=0.05), 9.0, 4.0, 3, relinearise_ranges=window)
    f.initialise(LAT, LON, 60.0, 0.0)
    true_lat, true_lon = geodesy.offset_position(
        LAT, LON, rng.normal(0.0, 60.0), rng.normal(0.0, 60.0)
    )
    b_lat, b_lon = geodesy.offset_position(LAT, LON, 0.0, 300.0)
    heading, speed = R(45.0), 1.5
    step_n, step_e = 0.1 * speed * math.cos(heading), 0.1 * speed * math.sin(heading)
    for k in range(1, 3001):
        t = 0.1 * k
        f.predict(t, 0.1, heading, speed, -1.0)
        true_lat, true_lon = geodesy.offset_position(true_lat, true_lon, step_n, step_e)
        if k % 100 == 0:
            r = geodesy.range_and_gradient(true_lat, true_lon, -1.0, b_lat, b_lon, -1.0)[0]
            z = r + rng.normal(scale=2.0)
            f.range_update(RangeMeas(t, t, z, "b", b_lat, b_lon, -1.0, -1.0, 2.0))
    err = np.array(geodesy.nearby_offset(float(f.x[0]), float(f.x[1]), true_lat, true_lon))
    nees = float(err @ np.linalg.solve(f.P[:2, :2], err))
    assert (f.relinearised > 0) == (window > 1)
    return math.hypot(*err), nees < 5.991  # chi-square, 2 degrees of freedom, 95 %


def test_relinearising_the_window_brings_the_filter_closer_and_keeps_it_honest() -> None:
    """Linearised where it stood, the EKF turns the first ranges' corrections the wrong way
    (its second-order range terms keep it from believing the result: its ellipse holds
    the truth).  Solving its window again brings it closer, and honest still."""
    plain = [_range_mission(s, 1) for s in range(24)]
    relin = [_range_mission(s, 30) for s in range(24)]
    rms_plain = math.sqrt(np.mean([e * e for e, _ in plain]))
    rms_relin = math.sqrt(np.mean([e * e for e, _ in relin]))
    assert rms_relin < 0.8 * rms_plain
    assert np.mean([inside for _, inside in plain]) >= 0.8
    assert np.mean([inside for _, inside in relin]) >= 0.8


_num = st.floats(allow_nan=True, allow_infinity=True, width=64)


def test_a_state_moved_outside_the_window_leaves_the_filters_covariance_a_covariance() -> None:
    """A caller that sets the state directly, without forgetting the window (as
    ``move_to`` does), leaves transitions that no longer describe the chain: the window
    then solves to a covariance with negative variances, which once made the next gate
    take a square root of one and raise.  The filter keeps its own instead."""
    f = RangeEKF(NoiseConfig(), 9.0, 4.0, 3, max_current_mps=2.0)
    f.initialise(LAT, LON, 3.0, 0.0)
    b_lat, b_lon = geodesy.offset_position(LAT, LON, 500.0, 200.0)
    rng = np.random.default_rng(1)
    true_n = true_e = 0.0
    heading = R(60.0)
    for k in range(1, 121):
        if k % 30 == 0:
            heading += R(90.0)
        if k == 31:
            off = np.zeros(len(f.x))
            off[:2] = 100.0, 100.0
            f.x = f.state_apply(f.x, off)
        for _ in range(100):
            f.predict(f.t + 0.1, 0.1, heading, 1.5, -2.0)
            true_n += 0.15 * math.cos(heading)
            true_e += 0.15 * math.sin(heading)
        v_lat, v_lon = geodesy.offset_position(LAT, LON, true_n, true_e)
        r = geodesy.ecef_distance(v_lat, v_lon, -2.0, b_lat, b_lon, -2.0) + rng.normal()
        f.range_update(RangeMeas(f.t, f.t, r, "boat", b_lat, b_lon, -2.0, -2.0, 1.0))
        assert np.linalg.eigvalsh(f.P).min() > 0.0


def _windows(seed: int) -> list[list[relinearise.Step]]:
    """Every window a filter solved on a run past a beacon whose position error it tracks."""
    rng = np.random.default_rng(seed)
    f = RangeEKF(NoiseConfig(current_init_std_mps=0.2), 9.0, 4.0, 3)
    f.initialise(LAT, LON, 40.0, 0.0)
    true_lat, true_lon = geodesy.offset_position(LAT, LON, 30.0, -20.0)
    b_lat, b_lon = geodesy.offset_position(LAT, LON, -200.0, 400.0)
    seen: list[list[relinearise.Step]] = []
    for k in range(1, 2401):
        t = 0.1 * k
        heading = R(30.0) if k < 1200 else R(150.0)
        f.predict(t, 0.1, heading, 1.4, -3.0)
        true_lat, true_lon = geodesy.offset_position(
            true_lat, true_lon, 0.14 * math.cos(heading) + 0.02, 0.14 * math.sin(heading)
        )
        if k % 100 == 0:
            r = geodesy.range_and_gradient(true_lat, true_lon, -3.0, b_lat, b_lon, -1.0)[0]
            m = RangeMeas(t, t - 0.6, r + rng.normal(scale=1.5), "b", b_lat, b_lon, -1.0, -3.0,
                          1.5, 3.0, 120.0)
            f.range_update(m)
            seen.append(list(f._steps))
    return [w for w in seen if len(w) >= 2]


def test_the_window_model_is_the_filters_range_where_it_fused_it() -> None:
    """At the prior, the plane's model is the exact range and Jacobian, near it the
    geodesic range, and its Jacobian is its own derivative."""
    f = RangeEKF(NoiseConfig(), 9.0, 4.0, 3)
    f.initialise(LAT, LON, 5.0, 0.0)
    for k in range(1, 201):
        f.predict(0.1 * k, 0.1, R(60.0), 1.5, -3.0)
    b_lat, b_lon = geodesy.offset_position(LAT, LON, -300.0, 250.0)
    m = RangeMeas(f.t - 0.3, f.t - 2.3, 0.0, "b", b_lat, b_lon, -1.0, -3.0, 1.0, 3.0, 120.0)
    f._track_beacon(m)
    exact, H_exact, sight = f._line_of_sight(m)
    r0, H0 = relinearise.window_range(np.zeros(8), sight)
    assert math.isclose(r0, exact, rel_tol=1e-12)
    assert np.allclose(H0, H_exact, atol=1e-12)
    # moved 150 m, the plane's range is the geodesic one within a millimetre
    x0 = f.x.copy()
    for dn, de in ((150.0, 0.0), (0.0, 150.0), (-100.0, 100.0)):
        d = np.zeros(8)
        d[0], d[1] = dn, de
        f.x = f.state_apply(x0, d, -3.0)
        exact, _ = f.predicted_range(m)
        assert abs(relinearise.window_range(d, sight)[0] - exact) < 1e-3
    f.x = x0
    d = np.array([12.0, -7.0, 0.05, -0.03, 0.0, 0.0, 1.5, -0.5])
    _, H = relinearise.window_range(d, sight)
    for j in (0, 1, 2, 3, 6, 7):
        e = np.zeros(8)
        e[j] = 1e-4 if j in (2, 3) else 1e-3
        plus, _ = relinearise.window_range(d + e, sight)
        minus, _ = relinearise.window_range(d - e, sight)
        assert H[j] == pytest.approx((plus - minus) / (2 * e[j]), abs=1e-6)


@pytest.mark.skipif(not relinearise.COMPILED, reason="built without a C compiler")
def test_the_compiled_window_solve_does_the_references_arithmetic() -> None:
    windows = _windows(5)
    assert len(windows) > 15
    for w in windows:
        compiled = relinearise.solve(w, 3, 0.5)
        reference = relinearise.smooth(w, relinearise.window_range, 3, 0.5)
        assert (compiled is None) == (reference is None)
        if compiled is not None and reference is not None:
            assert np.allclose(compiled[0], reference[0], rtol=1e-9, atol=1e-9)
            assert np.allclose(compiled[1], reference[1], rtol=1e-9, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(_num, _num, _num, _num), min_size=0, max_size=6), _num)
def test_any_window_is_solved_or_refused_without_raising(
    rows: list[tuple[float, float, float, float]], scale: float
) -> None:
    """Both the reference and the solve the filter calls (compiled where it can be)."""
    steps = []
    for a, b, z, r_var in rows:
        with np.errstate(all="ignore"):
            P = np.eye(8) * scale
        sight = relinearise.LineOfSight(a, 0.6, -0.8, b, 0.6, 0.8, 1.0, 0.5, True)
        steps.append(relinearise.Step(0.0, P, np.zeros(8), P, np.eye(8), P, sight, z, r_var,
                                      np.zeros(8), np.zeros(8)))
    for solved in (
        relinearise.smooth(steps, relinearise.window_range, 3, 0.5),
        relinearise.solve(steps, 3, 0.5),
    ):
        if solved is not None:
            d, P = solved
            assert np.all(np.isfinite(d)) and np.all(np.isfinite(P))


def test_the_compiled_solve_is_built_where_a_c_compiler_is_and_can_be_kept_out() -> None:
    if not os.environ.get("NAVD_PURE_PYTHON") and shutil.which("cc") is not None:
        assert relinearise.COMPILED
    code = "from navd.filter import relinearise; print(relinearise.COMPILED)"
    env = {**os.environ, "NAVD_PURE_PYTHON": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.stdout.strip() == "False", out.stderr
