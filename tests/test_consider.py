"""The consider covariance: what a faster-changing current adds to a filter's own."""

from __future__ import annotations

import numpy as np
from conftest import current_walk
from hypothesis import given, settings
from hypothesis import strategies as st

from navd.filter.consider import CurrentConsider


def _propagate(P: np.ndarray, dt: float, q2: float) -> np.ndarray:
    F, Q = current_walk(dt, q2)
    return F @ P @ F.T + Q


def test_it_is_the_difference_the_extra_walk_makes_under_the_filters_own_gains() -> None:
    """Two covariances of one estimator (its gains fixed), one with the water's walk as
    the filter assumes and one faster: their difference is the consider's, exactly, for
    position and current integrated between ranges."""
    rng = np.random.default_rng(7)
    own, extra = 0.002, 0.006
    c = CurrentConsider(extra)
    c.reset(0.0)
    slow = np.diag([4.0, 4.0, 0.01, 0.01])
    fast = slow.copy()
    t = 0.0
    for _ in range(40):
        dt = float(rng.uniform(2.0, 30.0))
        t += dt
        slow = _propagate(slow, dt, own**2)
        fast = _propagate(fast, dt, own**2 + extra**2)
        H = np.zeros(8)
        H[:2] = rng.normal(size=2)
        H[:2] /= np.linalg.norm(H[:2])
        H[2:4] = -rng.uniform(0.0, 10.0) * H[:2]
        r = 9.0
        K = np.zeros(8)
        K[:4] = slow @ H[:4] / (H[:4] @ slow @ H[:4] + r)  # the filter's gain, from its own P
        A = np.eye(4) - np.outer(K[:4], H[:4])
        slow = A @ slow @ A.T + r * np.outer(K[:4], K[:4])
        fast = A @ fast @ A.T + r * np.outer(K[:4], K[:4])
        c.update(t, K, H)
    t += 45.0
    slow, fast = _propagate(slow, 45.0, own**2), _propagate(fast, 45.0, own**2 + extra**2)
    dnn, dee, dne = c.position(t)
    d = fast - slow
    assert np.allclose([dnn, dee, dne], [d[0, 0], d[1, 1], d[0, 1]], rtol=1e-9, atol=1e-9)
    assert dnn > 0.0 and dee > 0.0


def test_a_new_walk_counts_from_its_time_and_keeps_the_error_before_it() -> None:
    """Water allowed for at one walk until ``t`` and at another after: the error until
    ``t`` stays the first walk's, and the rest integrates the second's."""
    a, b = 0.006, 0.002
    c = CurrentConsider(a)
    c.reset(0.0)
    c.set_walk(b, 100.0)
    P = _propagate(_propagate(np.zeros((4, 4)), 100.0, a * a), 60.0, b * b)
    assert np.allclose(c.covariance(160.0), P, rtol=1e-12, atol=1e-12)
    assert c.walk == b
    c.set_walk(float("nan"), 200.0)  # no walk at all: the one it has stays
    assert c.walk == b


@settings(max_examples=200, deadline=None)
@given(
    st.floats(allow_nan=True, allow_infinity=True),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=8, max_size=8),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=8, max_size=8),
)
def test_it_never_raises(t: float, k: list[float], h: list[float]) -> None:
    c = CurrentConsider(0.005)
    c.reset(0.0)
    c.update(t, np.array(k), np.array(h))
    c.set_walk(k[0], t)
    c.position(t + 1.0)
