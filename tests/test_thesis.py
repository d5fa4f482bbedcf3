"""The thesis mode, piece by piece against seed 000's equations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navd import geodesy
from navd.filter.common import RangeMeas
from navd.filter.thesis import (
    ThesisEKF,
    accept_or_reject,
    kinematic_jacobian,
    kinematic_model,
    measurement_model,
    metres_to_rad2,
    rad_to_metres_scale,
    radius_of_error,
)

R = math.radians
X0 = np.array([R(37.0482), R(-80.6679), 2e-8, -3e-8])


def test_kinematic_model_without_current_is_eq_2_5() -> None:
    x = X0.copy()
    x[2:] = 0.0
    radius = geodesy.centre_distance(x[0], x[1], 527.0)
    f = kinematic_model(x, 0.1, R(210.0), 1.1, radius)
    lat, lon = geodesy.great_circle_step(x[0], x[1], R(210.0), 0.11, radius)
    assert f[0] == pytest.approx(lat, abs=1e-15)
    assert f[1] == pytest.approx(lon, abs=1e-15)


def test_kinematic_model_adds_current_in_rad_per_s() -> None:
    radius = geodesy.centre_distance(X0[0], X0[1], 527.0)
    still = kinematic_model(X0, 10.0, 0.0, 0.0, radius)
    assert still[0] == pytest.approx(X0[0] + 10.0 * X0[2])
    assert still[1] == pytest.approx(X0[1] + 10.0 * X0[3])
    assert list(still[2:]) == list(X0[2:])


@pytest.mark.parametrize("heading", [0.0, 33.0, 90.0, 181.0, 275.0])
def test_state_jacobian_matches_finite_differences(heading: float) -> None:
    dt, speed = 0.1, 1.36
    radius = geodesy.centre_distance(X0[0], X0[1], 0.0)
    F = kinematic_jacobian(X0, dt, R(heading), speed, radius)
    eps = np.array([1e-6, 1e-6, 1e-5, 1e-5])
    for j in range(4):
        d = np.zeros(4)
        d[j] = eps[j]
        fd = (
            kinematic_model(X0 + d, dt, R(heading), speed, radius)
            - kinematic_model(X0 - d, dt, R(heading), speed, radius)
        ) / (2 * eps[j])
        np.testing.assert_allclose(F[:, j], fd, rtol=1e-4, atol=1e-9)
    # the structure of Appendix B
    assert F[0, 1] == 0.0 and F[0, 3] == 0.0 and F[1, 1] == 1.0
    assert F[0, 2] == dt and F[1, 3] == dt


def test_measurement_jacobian_matches_finite_differences() -> None:
    tgt = (R(37.0490), R(-80.6672), 527.0 - 3.0)
    h0, H = measurement_model(X0, 527.0 - 1.0, *tgt)
    for j in range(2):
        d = np.zeros(4)
        d[j] = 1e-8
        hp, _ = measurement_model(X0 + d, 527.0 - 1.0, *tgt)
        hm, _ = measurement_model(X0 - d, 527.0 - 1.0, *tgt)
        assert H[j] == pytest.approx((hp - hm) / 2e-8, rel=1e-5)
    assert H[2] == 0.0 and H[3] == 0.0


def test_covariance_conversions_eq_4_1_and_3_16_are_inverse() -> None:
    lat = R(38.32)
    pn, pe = metres_to_rad2(lat, 25.0, 16.0)
    sn, se = rad_to_metres_scale(lat)
    assert pn * sn * sn == pytest.approx(25.0)
    assert pe * se * se == pytest.approx(16.0)


def test_radius_of_error_is_eq_3_14() -> None:
    lat = R(37.05)
    pn, pe = metres_to_rad2(lat, 9.0, 16.0)
    P = np.diag([pn, pe, 0.0, 0.0])
    assert radius_of_error(P, lat, 144.0) == pytest.approx(13.0)  # sqrt(9 + 16 + 144)


def test_algorithm_1_accepts_within_one_radius() -> None:
    assert accept_or_reject(100.0, 109.9, 10.0)
    assert accept_or_reject(100.0, 90.0, 10.0)
    assert not accept_or_reject(100.0, 110.1, 10.0)


def _ekf() -> ThesisEKF:
    f = ThesisEKF(5.0, 0.3, 0.3, 0.0)
    f.initialise(X0[0], X0[1], 5.0, 0.0)
    return f


def test_initialisation_uses_metre_variances() -> None:
    f = _ekf()
    est = f.estimate()
    assert math.sqrt(est.var_n) == pytest.approx(5.0)
    assert math.sqrt(est.var_e) == pytest.approx(5.0)
    assert est.current_n == 0.0 and est.current_e == 0.0


def test_gps_resets_position() -> None:
    f = _ekf()
    for k in range(100):
        f.predict(0.1 * (k + 1), 0.1, 0.0, 1.0, 0.0)
    f.gps_update(X0[0] + 1e-5, X0[1], 3.0, 0.0)
    assert f.x[0] == X0[0] + 1e-5 and f.x[1] == X0[1]
    assert math.sqrt(f.estimate().var_n) == pytest.approx(5.0)


def test_range_rejected_outside_radius_and_state_unchanged() -> None:
    f = _ekf()
    tgt_lat, tgt_lon, _ = geodesy.destination(X0[0], X0[1], R(45.0), 100.0)
    m = RangeMeas(1.0, 0.9, 160.0, "udb", tgt_lat, tgt_lon, -3.0, -1.0, 3.0)
    before = f.x.copy()
    d = f.range_update(m)
    assert not d.accepted and d.reason == "gate"
    assert np.array_equal(before, f.x)
    good = RangeMeas(1.0, 0.9, 102.0, "udb", tgt_lat, tgt_lon, -3.0, -1.0, 3.0)
    assert f.range_update(good).accepted
