"""The consider covariances: what a faster-changing current, and a sound speed that is not
the water's, add to a filter's own."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from navd.filter.consider import CurrentConsider, RangeScaleConsider
from navd.filter.navparts import make_filter
from navd.settings import config_from_dict


def _propagate(P: np.ndarray, dt: float, q2: float) -> np.ndarray:
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    Q = np.zeros((4, 4))
    for i in (0, 1):
        Q[i, i] = q2 * dt**3 / 3.0
        Q[i, i + 2] = Q[i + 2, i] = q2 * dt**2 / 2.0
        Q[i + 2, i + 2] = q2 * dt
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
    c.position(t + 1.0)


def test_the_sound_speed_error_is_what_a_common_range_scale_does_under_the_filters_gains() -> None:
    """The estimator's error and the scale error together, exactly: every range is its
    true value less ``r s`` (h_s = -r), GPS fixes do not see ``s``.  The position block of
    that joint covariance, less the filter's own, is the consider's."""
    rng = np.random.default_rng(11)
    rel = 0.004
    c = RangeScaleConsider(rel)
    c.reset(0.0)
    own = np.diag([4.0, 4.0, 0.01, 0.01])
    joint = np.zeros((5, 5))  # (dn, de, dc_n, dc_e, s)
    joint[:4, :4] = own
    joint[4, 4] = rel**2
    t = 0.0
    for i in range(60):
        dt = float(rng.uniform(2.0, 30.0))
        t += dt
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        own = F @ own @ F.T
        Fj = np.eye(5)
        Fj[:4, :4] = F
        joint = Fj @ joint @ Fj.T
        if i % 15 == 14:  # a GPS fix at the surface
            H2 = np.zeros((2, 8))
            H2[0, 0] = H2[1, 1] = 1.0
            R = np.eye(2) * 9.0
            K2 = np.zeros((8, 2))
            K2[:4] = own @ H2[:, :4].T @ np.linalg.inv(H2[:, :4] @ own @ H2[:, :4].T + R)
            A = np.eye(4) - K2[:4] @ H2[:, :4]
            own = A @ own @ A.T + K2[:4] @ R @ K2[:4].T
            Aj = np.eye(5)
            Aj[:4, :4] = A
            joint = Aj @ joint @ Aj.T
            joint[:4, :4] += K2[:4] @ R @ K2[:4].T
            c.fixed(t, K2, H2)
            continue
        H = np.zeros(8)
        H[:2] = rng.normal(size=2)
        H[:2] /= np.linalg.norm(H[:2])
        H[2:4] = -rng.uniform(0.0, 10.0) * H[:2]
        r, rng_m = 9.0, float(rng.uniform(50.0, 2000.0))
        K = np.zeros(8)
        K[:4] = own @ H[:4] / (H[:4] @ own @ H[:4] + r)
        A = np.eye(4) - np.outer(K[:4], H[:4])
        own = A @ own @ A.T + r * np.outer(K[:4], K[:4])
        Aj = np.eye(5)
        Aj[:4, :4] = A
        Aj[:4, 4] = K[:4] * rng_m  # -K h_s
        joint = Aj @ joint @ Aj.T
        joint[:4, :4] += r * np.outer(K[:4], K[:4])
        c.ranged(t, K, H, rng_m)
    t += 45.0
    F = np.eye(4)
    F[0, 2] = F[1, 3] = 45.0
    own = F @ own @ F.T
    Fj = np.eye(5)
    Fj[:4, :4] = F
    joint = Fj @ joint @ Fj.T
    dnn, dee, dne = c.position(t)
    d = joint[:4, :4] - own
    assert np.allclose([dnn, dee, dne], [d[0, 0], d[1, 1], d[0, 1]], rtol=1e-9, atol=1e-9)
    assert dnn > 0.0 and dee > 0.0


def test_the_configured_sound_speed_error_reaches_both_beliefs_and_zero_turns_it_off() -> None:
    bank = make_filter(config_from_dict({}))
    for f in (bank.config, bank.uncal):  # type: ignore[attr-defined]
        assert f.scale is not None and f.scale.var > 0.0
    bank = make_filter(config_from_dict({"navigation": {"sound_speed": {"std_mps": 0.0}}}))
    assert bank.config.scale is None and bank.uncal.scale is None  # type: ignore[attr-defined]


@settings(max_examples=200, deadline=None)
@given(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(allow_nan=True, allow_infinity=True),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=8, max_size=8),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=8, max_size=8),
)
def test_the_sound_speed_consider_never_raises(
    t: float, r: float, k: list[float], h: list[float]
) -> None:
    c = RangeScaleConsider(0.003)
    c.reset(0.0)
    K, H = np.array(k), np.array(h)
    c.ranged(t, K, H, r)
    c.fixed(t, np.array([k, k]).T, np.array([h, h]))
    c.position(t + 1.0)
