"""The default mode's prediction step, compiled and in Python (navd/filter/ekf_step.py):
the compiled one is built where a compiler is, never raises, and does the reference's
arithmetic; a filter run on either gives the same estimates."""

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

from navd.filter import ekf_step
from navd.filter.ekf import RangeEKF
from navd.settings import NoiseConfig

NOISE = (0.1, math.radians(2.0), 10.0, 0.002, math.radians(0.01), 0.0005)
compiled = ekf_step._compiled
needs_compiled = pytest.mark.skipif(compiled is None, reason="built without a C compiler")


def _arrays(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = np.array([0.6, -1.3, 0.3, -0.2, 0.05, 1.04, 1.5, -2.0])
    A = rng.normal(size=(8, 8))
    return x, A @ A.T + np.eye(8), np.eye(8), np.zeros((8, 8))


def test_the_compiled_step_is_built_where_a_c_compiler_is() -> None:
    if os.environ.get("NAVD_PURE_PYTHON"):
        pytest.skip("kept out by NAVD_PURE_PYTHON")
    if shutil.which("cc") is None:
        pytest.skip("no C compiler here: the reference takes every step")
    assert ekf_step.COMPILED


def test_navd_pure_python_keeps_the_compiled_step_out() -> None:
    code = "from navd.filter import ekf_step; print(ekf_step.COMPILED)"
    env = {**os.environ, "NAVD_PURE_PYTHON": "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.stdout.strip() == "False", out.stderr


@needs_compiled
@given(
    seed=st.integers(0, 2**32 - 1),
    lat=st.floats(-1.5, 1.5),
    lon=st.floats(-math.pi, math.pi, exclude_max=True),
    heading=st.floats(-10.0, 10.0),
    speed=st.floats(0.0, 3.0),
    dt=st.floats(0.001, 1.0),
    hd=st.floats(-6000.0, 0.0),
    phi=st.floats(0.5, 1.0),
)
@settings(max_examples=300, deadline=None)
def test_the_compiled_step_does_the_references_arithmetic(
    seed: int, lat: float, lon: float, heading: float, speed: float, dt: float, hd: float,
    phi: float,
) -> None:
    xa, Pa, Fa, Qa = _arrays(seed)
    xa[0], xa[1] = lat, lon
    xb, Pb, Fb, Qb = xa.copy(), Pa.copy(), Fa.copy(), Qa.copy()
    q_off = 9.0 * (1.0 - phi * phi)
    ref = ekf_step.predict_step(xa, Pa, Fa, Qa, dt, heading, speed, hd, phi, q_off, NOISE)
    assert compiled is not None
    got = compiled(xb, Pb, Fb, Qb, dt, heading, speed, hd, phi, q_off, NOISE, ekf_step._GEODESIC)
    assert got is not None
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-15)
    # a position a few ulps apart at most (the geodesic's hypot is libm's, not Python's)
    np.testing.assert_allclose(xb, xa, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(Fb, Fa)
    np.testing.assert_allclose(Qb, Qa, rtol=1e-14, atol=1e-300)
    # the products summed in another order: the covariance agrees to rounding
    np.testing.assert_allclose(Pb, Pa, rtol=1e-12, atol=1e-12 * float(np.abs(Pa).max()))


@needs_compiled
@given(
    values=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=13, max_size=13),
)
@settings(max_examples=300, deadline=None)
def test_the_compiled_step_takes_any_numbers_without_raising(values: list[float]) -> None:
    x, P, F, Q = _arrays(0)
    x[:6] = values[:6]
    dt, heading, speed, hd, phi, q_off, p00 = values[6:]
    P[0, 0] = p00
    before = (x.copy(), P.copy())
    assert compiled is not None
    got = compiled(x, P, F, Q, dt, heading, speed, hd, phi, q_off, NOISE, ekf_step._GEODESIC)
    if got is None:
        # not an ordinary step: nothing changed, the reference takes it
        np.testing.assert_array_equal(x, before[0])
        np.testing.assert_array_equal(P, before[1])
    else:
        assert len(got) == 5


@needs_compiled
def test_arrays_it_cannot_borrow_go_to_the_reference() -> None:
    x, P, F, Q = _arrays(1)
    assert compiled is not None
    # a transposed view and a Fortran-ordered copy are not C-contiguous
    for bad_P in (np.asfortranarray(P), P.T, P.astype(np.float32), np.eye(9), [[0.0]]):
        args = (x, bad_P, F, Q, 0.1, 0.3, 1.5, -2.0, 1.0, 0.0, NOISE, ekf_step._GEODESIC)
        assert compiled(*args) is None
    # a step over 50 m (a long gap crossed in one step) is the reference's
    long_step = (x, P, F, Q, 100.0, 0.3, 1.5, -2.0, 1.0, 0.0, NOISE, ekf_step._GEODESIC)
    assert compiled(*long_step) is None


def _run(monkeypatch: pytest.MonkeyPatch, use_compiled: bool) -> list[tuple[float, ...]]:
    monkeypatch.setattr(ekf_step, "_compiled", compiled if use_compiled else None)
    f = RangeEKF(NoiseConfig(), 9.0, 20.0, 6)
    f.initialise(math.radians(37.1), math.radians(-80.6), 5.0, 0.0)
    out = []
    for k in range(1, 3001):  # five minutes at 10 Hz, turning
        f.predict(0.1 * k, 0.1, 0.002 * k, 1.5, -3.0)
        e = f.estimate()
        out.append((e.lat, e.lon, e.var_n, e.var_e, e.cov_ne))
    return out


@needs_compiled
def test_a_filter_gives_the_same_estimates_on_either_step(monkeypatch: pytest.MonkeyPatch) -> None:
    a = np.array(_run(monkeypatch, use_compiled=False))
    b = np.array(_run(monkeypatch, use_compiled=True))
    np.testing.assert_allclose(b[:, :2], a[:, :2], rtol=0.0, atol=1e-15)  # radians: 6 nm
    # the covariance to rounding (the north-east term passes through zero: against the
    # variances)
    np.testing.assert_allclose(b[:, 2:], a[:, 2:], rtol=1e-12, atol=1e-12 * a[:, 2:4].max())
