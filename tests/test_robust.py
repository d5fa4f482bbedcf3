"""Navigation that does not diverge: multipath bursts, a bounded current, and integrity."""

from __future__ import annotations

import math
import random

import pytest

from navd import geodesy
from navd.filter.common import RangeMeas
from navd.filter.ekf import RangeEKF
from navd.filter.integrity import DEGRADED, LOST, OK, Integrity, chi2_quantile
from navd.settings import NoiseConfig

R = math.radians
LAT, LON = R(38.32), R(-76.39)


def _mission(seed: int, outliers: float, current_e: float = 0.2, minutes: float = 25.0):
    """A vehicle running east and west under a boat 400 m north; ranges every 10 s.

    ``outliers`` of the replies read long by a uniform 3 to 300 m (heavy multipath).
    Returns the filter and the true position and current at the end.
    """
    rng = random.Random(seed)
    f = RangeEKF(NoiseConfig(), 9.0, 4.0, 3, max_current_mps=2.0)
    f.initialise(LAT, LON, 3.0, 0.0)
    true = (0.0, 0.0)  # metres north, east of the start
    heading = R(90.0)
    for k in range(1, int(minutes * 6) + 1):
        if k % 30 == 0:
            heading = R(270.0) if heading == R(90.0) else R(90.0)
        for _ in range(100):  # ten seconds at 10 Hz, compass and speed exact
            f.predict(f.t + 0.1, 0.1, heading, 1.5, -2.0)
            true = (true[0], true[1] + 0.1 * (1.5 * math.sin(heading) + current_e))
        if rng.random() < 0.35:
            continue  # the ping was lost
        vlat, vlon = geodesy.offset_position(LAT, LON, *true)
        blat, blon = geodesy.offset_position(LAT, LON, 400.0, 100.0)
        r = geodesy.ecef_distance(vlat, vlon, -2.0, blat, blon, -2.0) + rng.gauss(0.0, 1.0)
        if rng.random() < outliers:
            r += rng.uniform(3.0, 300.0)
        f.range_update(RangeMeas(f.t, f.t, r, "udb", blat, blon, -2.0, -2.0, 3.0))
    vlat, vlon = geodesy.offset_position(LAT, LON, *true)
    return f, (vlat, vlon), current_e


@pytest.mark.parametrize("seed", range(1, 7))
def test_heavy_multipath_never_moves_the_estimate_or_the_current_far(seed: int) -> None:
    """45 % of replies long by 3 to 300 m: bursts of them agree on nothing, so nothing moves."""
    f, (vlat, vlon), cur_e = _mission(seed, outliers=0.45)
    e, n, _ = geodesy.enu_offset(vlat, vlon, 0.0, f.x[0], f.x[1], 0.0)
    assert math.hypot(e, n) < 30.0
    assert math.hypot(f.x[2], f.x[3] - cur_e) < 0.25
    # and the filter knows roughly how well it knows: the truth within 3 sigma
    assert abs(n) < 3 * math.sqrt(f.P[0, 0]) + 5.0 and abs(e) < 3 * math.sqrt(f.P[1, 1]) + 5.0


def test_a_learned_current_never_exceeds_the_site_maximum() -> None:
    f = RangeEKF(NoiseConfig(current_init_std_mps=2.0), 9.0, 4.0, 3, max_current_mps=0.5)
    f.initialise(LAT, LON, 2.0, 0.0)
    blat, blon = geodesy.offset_position(LAT, LON, 100.0, 100.0)
    for k in range(30):  # ranges that say the vehicle runs away at 3 m/s
        for _ in range(100):
            f.predict(f.t + 0.1, 0.1, 0.0, 0.0, -1.0)
        vlat, vlon = geodesy.offset_position(LAT, LON, 0.0, -3.0 * 10.0 * (k + 1))
        r = geodesy.ecef_distance(vlat, vlon, -1.0, blat, blon, -1.0)
        f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1.0, -1.0, 1.0))
        assert math.hypot(f.x[2], f.x[3]) <= 0.5 + 1e-9


def test_chi2_quantile_matches_tables() -> None:
    # 99 % quantiles of chi-square (any statistics table)
    for dof, q in ((1, 6.635), (3, 11.345), (5, 15.086), (10, 23.209), (20, 37.566)):
        assert chi2_quantile(0.99, dof) == pytest.approx(q, rel=0.01)


def test_integrity_from_consistency_and_covariance() -> None:
    ig = Integrity(window=10, degraded_std_m=25.0, lost_std_m=100.0)
    rng = random.Random(3)
    for _ in range(10):  # innovations as the covariance claims: NIS ~ chi-square(1)
        ig.range(True, rng.gauss(0.0, 1.0) ** 2)
    assert ig.assess(5.0) == OK
    assert ig.assess(40.0) == DEGRADED and "40 m" in ig.reason
    assert ig.assess(150.0) == LOST
    assert ig.assess(math.nan) == LOST
    for _ in range(10):  # accepted, but three times the spread the filter claims
        ig.range(True, (3.0 * rng.gauss(0.0, 1.0)) ** 2 + 4.0)
    assert ig.assess(5.0) == DEGRADED and "NIS" in ig.reason
    for _ in range(10):
        ig.range(False, 50.0)
    assert ig.assess(5.0) == LOST and "refused" in ig.reason
    ig.clear()
    assert ig.assess(5.0) == OK


def test_integrity_after_a_range_refused_as_short() -> None:
    """Degraded from one range refused as reading short until a range is accepted; a
    range refused as long (multipath) is no such news, and a fix clears it."""
    ig = Integrity(window=10, degraded_std_m=25.0, lost_std_m=100.0)
    for _ in range(10):
        ig.range(True, 0.5)
    ig.range(False, 50.0, short=False)
    assert ig.assess(5.0) == OK
    ig.range(True, 0.5)
    ig.range(False, 50.0, short=True)
    assert ig.assess(5.0) == DEGRADED and "short" in ig.reason
    ig.range(False, 50.0, short=False)  # none accepted since: still in doubt
    assert ig.assess(5.0) == DEGRADED and "short" in ig.reason
    ig.range(True, 0.5)
    assert ig.assess(5.0) == OK
    ig.range(False, 50.0, short=True)
    ig.clear()
    assert ig.assess(5.0) == OK


def test_integrity_after_a_range_that_placed_the_estimate_alone() -> None:
    """A range whose update moved the estimate by most of its residual (after a gap) is
    degraded until a range is accepted that the estimate could have refused; a refusal
    in between checks nothing, and a fix clears it.  A mode that does not say how far a
    range pulled it (NaN) is never held."""
    ig = Integrity(window=10, degraded_std_m=25.0, lost_std_m=100.0)
    for _ in range(10):
        ig.range(True, 0.5, pull=0.5)
    assert ig.assess(5.0) == OK
    ig.range(True, 0.5, pull=0.95)
    assert ig.assess(5.0) == DEGRADED and "placed" in ig.reason
    ig.range(False, 50.0)  # refused as long: a reflection, or the true one; no news
    assert ig.assess(5.0) == DEGRADED and "placed" in ig.reason
    ig.range(True, 0.5, pull=0.9)  # placed again: still one range's word
    assert ig.assess(5.0) == DEGRADED
    ig.range(True, 0.5, pull=0.3)
    assert ig.assess(5.0) == OK
    ig.range(True, 0.5, pull=0.95)
    ig.clear()
    assert ig.assess(5.0) == OK
    ig.range(True, 0.5, pull=math.nan)
    assert ig.assess(5.0) == OK
