"""A net of two transponders: the other crossing of their circles (navd/filter/mirror.py)."""

from __future__ import annotations

import math
import random

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from navd import geodesy
from navd.filter.bank import CalibrationBank
from navd.filter.common import RangeMeas, StateEstimate
from navd.filter.ekf import RangeEKF
from navd.settings import NoiseConfig

R = math.radians
LAT, LON = R(37.05), R(-80.66)
HD = -20.0  # transponders' and vehicle's height (m below the ellipsoid)
CHI2_2DOF_95 = 5.99
CHI2_2DOF_99 = 9.21
# two transponders 1.6 km apart on an east-west baseline through the origin
NET = {"t1": (0.0, -800.0), "t2": (0.0, 800.0)}


def _d2(est: StateEstimate, n: float, e: float) -> tuple[float, float]:
    """The truth at (n, e) from the origin: its distance from the estimate (m) and its
    squared Mahalanobis distance in the published ellipse."""
    en, ee = geodesy.nearby_offset(LAT, LON, est.lat, est.lon)
    P = np.array([[est.var_n, est.cov_ne], [est.cov_ne, est.var_e]])
    v = np.array([n - en, e - ee])
    return math.hypot(*v), float(v @ np.linalg.solve(P, v))


def _fly(
    start: tuple[float, float],
    heading_deg: float,
    guess: tuple[float, float],
    std_m: float,
    minutes: float,
    net: dict[str, tuple[float, float]],
    seed: int = 1,
) -> tuple[CalibrationBank, float, float]:
    """A vehicle from ``start`` (north, east, m) at 1.5 m/s on ``heading_deg``, the bank
    started at ``guess`` with ``std_m``; ranges of 1 m noise from each transponder in
    turn every 4 s.  The bank and the truth at the end."""
    rng = random.Random(seed)
    bank = CalibrationBank(RangeEKF(NoiseConfig(), 9.0, 4.0, 3, max_current_mps=2.0))
    glat, glon = geodesy.offset_position(LAT, LON, *guess)
    bank.initialise(glat, glon, std_m, 0.0)
    where = {k: geodesy.offset_position(LAT, LON, n, e) for k, (n, e) in net.items()}
    n, e = start
    h = R(heading_deg)
    names = sorted(net)
    for k in range(1, int(minutes * 15) + 1):
        for _ in range(40):
            bank.predict(bank.config.t + 0.1, 0.1, h, 1.5, HD)
            n += 0.15 * math.cos(h)
            e += 0.15 * math.sin(h)
        vlat, vlon = geodesy.offset_position(LAT, LON, n, e)
        name = names[k % len(names)]
        blat, blon = where[name]
        r = geodesy.ecef_distance(vlat, vlon, HD, blat, blon, HD) + rng.gauss(0.0, 1.0)
        t = bank.config.t
        bank.range_update(RangeMeas(t, t, r, name, blat, blon, HD, HD, 1.0))
    return bank, n, e


def test_the_other_crossing_stays_inside_the_ellipse_of_a_filter_that_took_the_wrong_one() -> None:
    """A vehicle 60 m north of the baseline, running along it; the filter starts 40 m
    south of it, its std 60 m (a quarter of its belief beyond the baseline).  The ranges
    give the distance from the baseline, not the side: the filter settles on the mirror
    image, 120 m off, surer than that.  The twin holds the truth, and the published
    ellipse with it: the truth inside the 99 % ellipse (the 95 % one of a mixture's
    moments holds a mode 120 m off only at a weight above a sixth, and the filter's own
    ellipse put an eighth beyond the baseline when the two parted), the std too wide
    for ``ok``."""
    bank, n, e = _fly((60.0, -300.0), 90.0, (-40.0, -300.0), 60.0, 5.0, NET)
    followed = bank.followed.estimate()
    off, _ = _d2(followed, n, e)
    assert off > 100.0  # the filter's own mean is at the other crossing
    assert math.sqrt(followed.var_n) < 10.0  # and it alone is sure of it
    twin = bank.mirror.twin
    assert twin is not None and 0.1 < bank.mirror.w < 0.5
    assert _d2(twin.estimate(), n, e)[0] < 5.0
    published = bank.estimate()
    _, d2 = _d2(published, n, e)
    assert d2 < CHI2_2DOF_99
    assert math.sqrt(published.var_n) > 25.0  # integrity's degraded limit


def test_a_vehicle_that_crosses_the_baseline_keeps_no_twin() -> None:
    """Dead reckoning across the baseline says which side: the vehicle runs north across
    it from 150 m south, the filter started on it with a std of 40 m.  Ten minutes on,
    750 m north, the published ellipse is the bank's own and the truth within it."""
    bank, n, e = _fly((-150.0, 200.0), 0.0, (-150.0, 200.0), 40.0, 10.0, NET)
    assert bank.mirror.twin is None
    published = bank.estimate()
    bank.mirror.reset()
    assert published.var_n < 1.01 * bank.estimate().var_n  # the bank's own, as without
    off, d2 = _d2(published, n, e)
    assert off < 10.0 and d2 < CHI2_2DOF_95


def test_a_third_transponder_ends_the_twin() -> None:
    """With a third transponder off the baseline, the ranges tell the side themselves."""
    net = {**NET, "t3": (600.0, 0.0)}
    bank, n, e = _fly((60.0, -300.0), 90.0, (-40.0, -300.0), 60.0, 5.0, net)
    assert bank.mirror.twin is None
    off, d2 = _d2(bank.estimate(), n, e)
    assert off < 10.0 and d2 < CHI2_2DOF_95


def test_a_gps_fix_or_a_restart_ends_the_twin() -> None:
    bank, _, _ = _fly((60.0, -300.0), 90.0, (-40.0, -300.0), 60.0, 2.0, NET)
    assert bank.mirror.twin is not None
    lat, lon = geodesy.offset_position(LAT, LON, 60.0, 0.0)
    bank.gps_update(lat, lon, 3.0, 0.0)
    assert bank.mirror.twin is None
    bank, _, _ = _fly((60.0, -300.0), 90.0, (-40.0, -300.0), 60.0, 2.0, NET)
    x, P, held = bank.checkpoint()
    bank.restore(x, P, 0.0, held)
    assert bank.mirror.twin is None


# what the navigator can hand a filter: transponders that are somewhere (records.py's
# bounds), and ranges of any length, or none the float could hold
near = st.one_of(st.floats(-0.001, 0.001), st.floats(-0.5, 0.5), st.just(0.0))
any_float = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["t1", "t2", "t3"]),
            near,
            near,
            st.one_of(st.floats(0.0, 3000.0), any_float),
            st.floats(0.1, 30.0),
            st.floats(0.0, 6.3),
        ),
        max_size=40,
    ),
    st.floats(1.0, 300.0),
)
def test_no_net_of_any_ranges_makes_the_twin_raise(
    ranges: list[tuple[str, float, float, float, float, float]], std_m: float
) -> None:
    """Transponders anywhere, together or apart, ranges of any length, ellipses of any
    size: the bank with its twin never raises, and a twin is only ever a finite one of a
    weight in (0, 1)."""
    bank = CalibrationBank(RangeEKF(NoiseConfig(), 9.0, 4.0, 3, max_current_mps=2.0))
    bank.initialise(LAT, LON, std_m, 0.0)
    for name, dlat, dlon, r, dt, heading in ranges:
        t = bank.config.t + dt
        bank.predict(t, dt, heading, 1.5, HD)
        bank.range_update(RangeMeas(t, t, r, name, LAT + dlat, LON + dlon, HD, HD, 1.0))
        bank.estimate()
        twin = bank.mirror.twin
        if twin is not None:
            assert 0.0 < bank.mirror.w < 1.0
            assert np.isfinite(twin.x).all() and np.isfinite(twin.P).all()
