"""The calibration bank: honest when the config's priors are wrong, and the config's mean
until the config filter's own estimate refutes them."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from navd import geodesy
from navd.filter.bank import CalibrationBank, range_likelihood, uncalibrated_noise
from navd.filter.common import RangeMeas, StateEstimate
from navd.filter.ekf import RangeEKF
from navd.settings import NoiseConfig

R = math.radians
LAT, LON = R(38.32), R(-76.39)
CHI2_2DOF_99 = 9.21


def _inside99(est: StateEstimate, lat: float, lon: float) -> bool:
    e, n, _ = geodesy.enu_offset(est.lat, est.lon, 0.0, lat, lon, 0.0)
    P = np.array([[est.var_n, est.cov_ne], [est.cov_ne, est.var_e]])
    v = np.array([n, e])
    return float(v @ np.linalg.solve(P, v)) <= CHI2_2DOF_99


def _run(noise: NoiseConfig, current: tuple[float, float], seed: int, minutes: float = 30.0,
         outliers: float = 0.0) -> tuple[CalibrationBank, list[tuple[bool, bool]]]:
    """A vehicle on legs of 5 minutes under a boat 500 m away, ranges every 10 s.

    Per range after the first five minutes: is the truth inside the bank's 99 %
    ellipse, and inside the config filter's own?
    """
    rng = random.Random(seed)
    bank = CalibrationBank(RangeEKF(noise, 9.0, 4.0, 3, max_current_mps=2.0))
    bank.initialise(LAT, LON, 3.0, 0.0)
    blat, blon = geodesy.offset_position(LAT, LON, 500.0, 200.0)
    true_n = true_e = 0.0
    heading = R(rng.uniform(0.0, 360.0))
    seen = []
    for k in range(1, int(minutes * 6) + 1):
        if k % 30 == 0:
            heading += R(rng.choice([90.0, 180.0, 270.0]))
        for _ in range(100):
            bank.predict(bank.config.t + 0.1, 0.1, heading, 1.5, -2.0)
            true_n += 0.1 * (1.5 * math.cos(heading) + current[0])
            true_e += 0.1 * (1.5 * math.sin(heading) + current[1])
        vlat, vlon = geodesy.offset_position(LAT, LON, true_n, true_e)
        r = geodesy.ecef_distance(vlat, vlon, -2.0, blat, blon, -2.0) + rng.gauss(0.0, 1.0)
        if rng.random() < outliers:
            r += rng.uniform(3.0, 300.0)
        t = bank.config.t
        bank.range_update(RangeMeas(t, t, r, "boat", blat, blon, -2.0, -2.0, 1.0))
        if k > 30:
            seen.append((_inside99(bank.estimate(), vlat, vlon),
                         _inside99(bank.config.estimate(), vlat, vlon)))
    return bank, seen


def test_a_current_ten_times_its_prior_stays_inside_the_published_ellipse() -> None:
    """The config says 0.04 m/s; the water runs at 0.45 m/s.  The config filter alone
    loses the truth from its ellipse; the bank's ellipse keeps it."""
    bank_in, alone_in = [], []
    for seed in range(1, 9):
        _, seen = _run(NoiseConfig(current_init_std_mps=0.04), (0.25, -0.37), seed)
        bank_in += [b for b, _ in seen]
        alone_in += [a for _, a in seen]
    alone, bank = sum(alone_in) / len(alone_in), sum(bank_in) / len(bank_in)
    assert alone < 0.5  # the case the bank is for
    # one of the eight loses it in both beliefs (a single beacon's geometry)
    assert bank >= 0.85


def test_a_right_config_keeps_the_config_filters_position_and_about_its_ellipse() -> None:
    """With the config right, heavy multipath: the published position is the config
    filter's, and the truth inside its ellipse.  The ellipse is wider than the config
    filter's own by what the other belief allows (ten times the priors, and water that may
    turn like the site's strongest tide), with the ranges unable to tell the two apart
    here; but within twice its one-sigma size after 20 minutes."""
    bank, seen = _run(NoiseConfig(), (0.1, 0.05), 3, minutes=20.0, outliers=0.3)
    a, b = bank.config.estimate(), bank.estimate()
    assert (b.lat, b.lon, b.current_n, b.current_e) == (a.lat, a.lon, a.current_n, a.current_e)
    assert b.var_n + b.var_e < 2.0**2 * (a.var_n + a.var_e)
    assert sum(x for x, _ in seen) / len(seen) >= 0.95


def test_the_ellipse_keeps_a_share_of_the_other_belief_however_sure_the_ranges() -> None:
    """Ranges test a belief only along their line of sight, so however far they drive the
    weight of the uncalibrated belief down, the published ellipse keeps the share of its
    spread that the chance of a change before the next range gives it."""
    bank, _ = _run(NoiseConfig(current_init_std_mps=0.1), (0.25, -0.37), 2, minutes=8.0)
    assert not bank.refuted  # so the published belief is the config's
    a, b = bank.config.estimate(), bank.uncal.estimate()
    n, e = geodesy.nearby_offset(a.lat, a.lon, b.lat, b.lon)
    other = b.var_n + b.var_e + n * n + e * e
    assert other > 4.0 * (a.var_n + a.var_e)  # the two beliefs differ, or this tests nothing
    for w in (0.0, 1e-9, 0.01, 0.5):
        bank.w_uncal = w
        est = bank.estimate()
        assert est.var_n + est.var_e >= 0.05 * other + 0.95 * (a.var_n + a.var_e) - 1e-9


def test_the_uncalibrated_belief_is_wider_but_bounded() -> None:
    nz = NoiseConfig(current_init_std_mps=0.05, heading_bias_init_std_deg=1.0,
                     speed_scale_init_std=0.1)
    u = uncalibrated_noise(nz, max_current_mps=2.0)
    assert u.current_init_std_mps == 0.5
    assert u.heading_bias_init_std_deg == 10.0
    assert u.speed_scale_init_std == 0.25  # ten times would be a scale of 0 or 2
    # a config already wider than the caps is kept as it is
    wide = uncalibrated_noise(NoiseConfig(current_init_std_mps=3.0), max_current_mps=2.0)
    assert wide.current_init_std_mps == 3.0


def test_a_restored_checkpoint_widens_only_the_uncalibrated_calibration() -> None:
    bank, _ = _run(NoiseConfig(), (0.1, 0.0), 1, minutes=8.0)
    x, P = bank.config.x.copy(), bank.config.P.copy()
    fresh = CalibrationBank(RangeEKF(NoiseConfig(), 9.0, 4.0, 3))
    fresh.initialise(float(x[0]), float(x[1]), 1.0, 0.0)
    fresh.restore(x, P, 25.0)
    assert np.allclose(fresh.config.P[2:, 2:], P[2:, 2:])
    u = uncalibrated_noise(NoiseConfig(), 2.0)
    k = u.current_init_std_mps / NoiseConfig().current_init_std_mps
    assert math.isclose(fresh.uncal.P[2, 2], P[2, 2] * k * k)
    assert math.isclose(fresh.uncal.P[0, 0], P[0, 0] + 25.0)


def test_the_likelihood_of_any_range_is_finite_and_positive() -> None:
    for residual, s in ((0.0, 1.0), (1e6, 1.0), (float("nan"), 4.0), (3.0, 0.0), (3.0, math.inf),
                        (-math.inf, 2.0)):
        v = range_likelihood(residual, s)
        assert math.isfinite(v) and v > 0.0
    # an outlier is evidence for neither belief: far residuals all have the floor's likelihood
    assert math.isclose(range_likelihood(500.0, 9.0), range_likelihood(900.0, 25.0))


def test_the_estimate_says_how_much_the_ranges_doubt_the_calibration() -> None:
    """``calibration_doubt``: near 0.5 while the ranges cannot tell, towards 1 when they say
    the config's priors were wrong."""
    wrong = [_run(NoiseConfig(current_init_std_mps=0.04), (0.25, -0.37), s)[0] for s in (1, 2, 6)]
    right = [_run(NoiseConfig(current_init_std_mps=0.45), (0.25, -0.37), s)[0] for s in (1, 2, 6)]
    doubt = []
    for b in wrong + right:
        c = b.corrections()
        assert c is not None and c.calibration_doubt is not None
        assert 0.0 <= c.calibration_doubt <= 1.0
        doubt.append(c.calibration_doubt)
    assert sum(doubt[:3]) / 3 > 0.65
    assert max(doubt[3:]) < 0.55


def test_refuted_priors_publish_the_uncalibrated_belief() -> None:
    """The config says 0.04 m/s; the water runs at 0.45 m/s.  Re-acquisitions drag the
    config filter's current far past its priors; from then on the bank publishes the
    uncalibrated filter's estimate, which holds the water's current, and says so."""
    for seed in range(1, 9):
        bank, _ = _run(NoiseConfig(current_init_std_mps=0.04), (0.25, -0.37), seed)
        assert bank.refuted
        est, u = bank.estimate(), bank.uncal.estimate()
        assert (est.lat, est.lon, est.current_n, est.current_e) == (u.lat, u.lon, u.current_n,
                                                                    u.current_e)
        assert math.hypot(est.current_n - 0.25, est.current_e + 0.37) < 0.1
        c = bank.corrections()
        assert c is not None and c.calibration_refuted is True
        assert bank.history is bank.uncal.history


def test_a_refuted_belief_never_narrows_the_published_ellipse() -> None:
    """Once refuted, the config belief's covariance came of priors the data refuted: even
    where it agrees with the followed belief on the place and is far surer of it, the
    published ellipse holds the followed belief's own, and the config's mean beside it."""
    bank, _ = _run(NoiseConfig(current_init_std_mps=0.04), (0.25, -0.37), 1)
    assert bank.refuted
    bank.config.x = bank.uncal.x.copy()
    bank.config.P = bank.uncal.P * 1e-4
    pub, own = bank.estimate(), bank.uncal.estimate()

    def cov(e: StateEstimate) -> np.ndarray:
        return np.array([[e.var_n, e.cov_ne], [e.cov_ne, e.var_e]])

    assert np.linalg.eigvalsh(cov(pub) - cov(own)).min() > -1e-9 * own.var_n
    lat, _ = geodesy.offset_position(bank.config.x[0], bank.config.x[1], 100.0, 0.0)
    bank.config.x[0] = lat  # the config belief 100 m north: held too
    assert bank.estimate().var_n > own.var_n + 0.01 * 100.0**2


def test_a_right_config_is_never_refuted() -> None:
    for seed in range(1, 5):
        bank, _ = _run(NoiseConfig(), (0.1, 0.05), seed, minutes=20.0, outliers=0.3)
        assert not bank.refuted
        c = bank.corrections()
        assert c is not None and c.calibration_refuted is False


def test_a_restored_checkpoint_starts_unrefuted() -> None:
    bank, _ = _run(NoiseConfig(current_init_std_mps=0.04), (0.25, -0.37), 1)
    assert bank.refuted
    x, P = bank.x.copy(), bank.P.copy()
    bank.restore(x, P, 25.0)
    assert not bank.refuted
    assert np.allclose(bank.config.x, x)


def _net_bank(beacons: list[str], minutes: float) -> CalibrationBank:
    """A vehicle running north at 1.5 m/s past surveyed transponders, one reply every 10 s
    from each of ``beacons`` in turn."""
    bank = CalibrationBank(RangeEKF(NoiseConfig(), 9.0, 4.0, 3, max_current_mps=2.0))
    bank.initialise(LAT, LON, 3.0, 0.0)
    where = {"t1": (300.0, 400.0), "t2": (600.0, -400.0)}
    for k in range(1, int(minutes * 6) + 1):
        for _ in range(100):
            bank.predict(bank.config.t + 0.1, 0.1, 0.0, 1.5, -2.0)
        name = beacons[k % len(beacons)]
        blat, blon = geodesy.offset_position(LAT, LON, *where[name])
        vlat, vlon = geodesy.offset_position(LAT, LON, 1.5 * bank.config.t, 0.0)
        r = geodesy.ecef_distance(vlat, vlon, -2.0, blat, blon, -20.0)
        t = bank.config.t
        bank.range_update(RangeMeas(t, t, r, name, blat, blon, -20.0, -2.0, 1.0, 0.5, math.inf))
    return bank


def test_a_net_carries_the_considered_tide_in_the_uncalibrated_gains() -> None:
    """One transponder cannot see the water change across its line of sight, so the
    uncalibrated belief only considers a tide; a second one can, and from its first reply
    that belief's own walk keeps up with such a tide instead, its covariance taking over
    what the consider held (its ellipse does not jump)."""
    one = _net_bank(["t1"], 10.0)
    assert one.uncal.consider is not None
    u = one.uncal
    before, own = u.estimate(), float(u.P[0, 0])
    assert before.var_n - own > 1.0  # the consider held more than a square metre
    u.carry_considered_walk()
    after = u.estimate()
    assert u.consider is None
    for a, b in ((before.var_n, after.var_n), (before.var_e, after.var_e),
                 (before.cov_ne, after.cov_ne)):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-9)
    net = _net_bank(["t1", "t2"], 10.0)
    assert net.uncal.consider is None
    assert net.config.consider is None
