"""Seed 004 static least-squares fix: exact with exact ranges, covariance fits the noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navd import geodesy
from navd.filter.lsfix import RangeTo, least_squares_fix

R = math.radians
LAT, LON = R(48.15), R(-122.40)  # Port Susan, the seed's test site
# three surface nodes about 1 km from the vehicle (seed 004 section IV)
NODES = [(1000.0, 0.0), (-500.0, 866.0), (-500.0, -866.0)]


def _ranges(truth: tuple[float, float], noise: np.ndarray | None = None, std: float = 1.0):
    out = []
    for i, (n, e) in enumerate(NODES):
        blat, blon = geodesy.offset_position(LAT, LON, n, e)
        r = geodesy.ecef_distance(truth[0], truth[1], -50.0, blat, blon, 0.0)
        out.append(RangeTo(blat, blon, 0.0, r + (0.0 if noise is None else noise[i]), std))
    return out


def test_exact_ranges_give_the_exact_position() -> None:
    truth = geodesy.offset_position(LAT, LON, 120.0, -340.0)
    fix = least_squares_fix(_ranges(truth), -50.0)
    assert fix is not None and fix.iterations < 10
    e, n, _ = geodesy.enu_offset(truth[0], truth[1], 0, fix.lat, fix.lon, 0)
    assert math.hypot(e, n) < 1e-3


def test_covariance_matches_the_scatter() -> None:
    rng = np.random.default_rng(4)
    truth = geodesy.offset_position(LAT, LON, -200.0, 150.0)
    nees = []
    for _ in range(300):
        fix = least_squares_fix(_ranges(truth, rng.normal(0, 1.0, 3)), -50.0)
        e, n, _ = geodesy.enu_offset(truth[0], truth[1], 0, fix.lat, fix.lon, 0)
        d = np.array([n, e])
        nees.append(float(d @ np.linalg.solve(fix.cov_ne, d)))
    assert np.mean(nees) == pytest.approx(2.0, abs=0.35)  # chi-square, 2 degrees of freedom


def test_too_few_ranges_or_degenerate_geometry_gives_no_fix() -> None:
    truth = geodesy.offset_position(LAT, LON, 0.0, 0.0)
    assert least_squares_fix(_ranges(truth)[:2], -50.0) is None
    # three beacons on one line through the vehicle: east is unobservable
    line = []
    for n in (300.0, 600.0, 900.0):
        blat, blon = geodesy.offset_position(LAT, LON, n, 0.0)
        line.append(
            RangeTo(blat, blon, -50.0, geodesy.ecef_distance(LAT, LON, -50, blat, blon, -50), 1.0)
        )
    assert least_squares_fix(line, -50.0, guess=(LAT, LON)) is None
