"""The default filter: round-trip range model, Joseph update, gate and re-acquisition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navd import geodesy
from navd.filter.common import Held, RangeMeas
from navd.filter.ekf import N_STATES, RangeEKF
from navd.settings import NoiseConfig

R = math.radians
LAT, LON = R(38.32), R(-76.39)


def _ekf(pos_std: float = 5.0, noise: NoiseConfig | None = None) -> RangeEKF:
    f = RangeEKF(noise or NoiseConfig(), 9.0, 4.0, 3)
    f.initialise(LAT, LON, pos_std, 0.0)
    return f


def _run(f: RangeEKF, seconds: float, heading: float = R(90.0), speed: float = 1.5) -> None:
    t0 = f.t
    for k in range(1, int(seconds * 10) + 1):
        f.predict(t0 + 0.1 * k, 0.1, heading, speed, -1.0)


def _beacon(north: float, east: float) -> tuple[float, float]:
    return geodesy.offset_position(LAT, LON, north, east)


def test_round_trip_range_uses_the_position_at_the_ping() -> None:
    f = _ekf()
    _run(f, 20.0)  # eastward at 1.5 m/s
    blat, blon = _beacon(0.0, 0.0)  # beacon at the start, vehicle 30 m east of it
    m = RangeMeas(f.t, f.t - 2.0, 0.0, "b", blat, blon, -1.0, -1.0, 1.0)
    predicted, _ = f.predicted_range(m)
    # out leg from 27 m east, back leg to 30 m east: the mean is 28.5 m
    assert predicted == pytest.approx(28.5, abs=0.05)


def test_range_jacobian_matches_finite_differences() -> None:
    f = _ekf()
    _run(f, 20.0)
    blat, blon = _beacon(-80.0, 40.0)
    m = RangeMeas(f.t, f.t - 3.0, 0.0, "b", blat, blon, -1.0, -1.0, 1.0)
    _, H = f.predicted_range(m)
    x0 = f.x.copy()
    for j, eps in ((0, 0.01), (1, 0.01)):
        dx = np.zeros(N_STATES)
        dx[j] = eps
        f.x = f.state_apply(x0, dx, -1.0)
        hp, _ = f.predicted_range(m)
        f.x = f.state_apply(x0, -dx, -1.0)
        hm, _ = f.predicted_range(m)
        assert H[j] == pytest.approx((hp - hm) / (2 * eps), abs=1e-4)
    f.x = x0


def test_covariance_stays_symmetric_positive_definite() -> None:
    rng = np.random.default_rng(3)
    f = _ekf()
    for k in range(300):
        _run(f, 1.0, heading=R(rng.uniform(0, 360)))
        if k % 10 == 0:
            blat, blon = _beacon(*rng.uniform(-300, 300, 2))
            est, _ = f.predicted_range(RangeMeas(f.t, f.t - 0.2, 0, "b", blat, blon, -1, -1, 3.0))
            f.range_update(
                RangeMeas(f.t, f.t - 0.2, est + rng.normal(0, 3), "b", blat, blon, -1, -1, 3.0)
            )
        assert np.array_equal(f.P, f.P.T)
        assert np.all(np.linalg.eigvalsh(f.P) > 0)


def test_long_ranges_get_the_tighter_gate() -> None:
    f = _ekf(pos_std=2.0)
    blat, blon = _beacon(100.0, 0.0)
    est, H = f.predicted_range(RangeMeas(0.0, 0.0, 0, "b", blat, blon, -1, -1, 1.0))
    s = math.sqrt(float(H @ f.P @ H) + 1.0)
    short = f.range_update(RangeMeas(0.0, 0.0, est - 2.5 * s, "b", blat, blon, -1, -1, 1.0))
    f2 = _ekf(pos_std=2.0)
    long_ = f2.range_update(RangeMeas(0.0, 0.0, est + 2.5 * s, "b", blat, blon, -1, -1, 1.0))
    assert short.accepted and not long_.accepted


def test_never_locked_out_after_drifting() -> None:
    """The Chesapeake failure: the estimate drifted far and the prior is too small."""
    noise = NoiseConfig(current_init_std_mps=0.01)
    f = _ekf(pos_std=2.0, noise=noise)
    # the truth is 80 m north of where the filter thinks it is
    true_lat, true_lon = geodesy.offset_position(LAT, LON, 80.0, 0.0)
    decisions = []
    beacons = [(150.0, 150.0), (-150.0, 100.0), (0.0, -200.0)]
    for k in range(18):
        blat, blon = _beacon(*beacons[k % 3])
        r = geodesy.ecef_distance(true_lat, true_lon, -1.0, blat, blon, -1.0)
        f.t += 10.0
        decisions.append(f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1, -1, 1.0)))
    assert not decisions[0].accepted
    # Six ranges must agree before the estimate moves, and an 80 m jump must be one a
    # current could have made since the last fix: this one, put there at once, takes
    # a few more pings to become plausible.  It is never locked out.
    reacquired = [i for i, d in enumerate(decisions) if d.reason == "gate_reacquire"]
    assert len(reacquired) == 1 and reacquired[0] <= 9
    assert sum(d.accepted for d in decisions) >= 6
    e, n, _ = geodesy.enu_offset(true_lat, true_lon, 0, f.x[0], f.x[1], 0)
    assert math.hypot(e, n) < 10.0


def test_learns_the_error_of_the_position_the_beacon_reports() -> None:
    """Pinned by GPS at the surface, ranges reveal where the beacon really is."""
    f = _ekf(pos_std=3.0)
    true_lat, true_lon = _beacon(150.0, 0.0)
    rep_lat, rep_lon = _beacon(170.0, 0.0)  # its GPS reads 20 m north of the truth
    for _ in range(12):
        _run(f, 10.0, speed=0.0)
        f.gps_update(LAT, LON, 3.0, 0.0)
        r = geodesy.ecef_distance(LAT, LON, -1.0, true_lat, true_lon, -1.0)
        m = RangeMeas(f.t, f.t, r, "udb", rep_lat, rep_lon, -1.0, -1.0, 1.0, 7.0, 120.0)
        assert f.range_update(m).accepted
    assert f.primary == "udb"
    assert f.x[6] == pytest.approx(-20.0, abs=3.0)  # true minus reported, north
    assert math.sqrt(f.P[6, 6]) < 5.0


def test_a_learned_beacon_offset_fades_as_the_beacon_gps_wanders() -> None:
    """The offset is a Gauss-Markov process: unobserved, its estimate decays with its variance.

    Without the decay the filter would keep a surface calibration for ever while the
    boat's GPS error wanders off, and bias every range of a long dive.
    """
    f = _ekf(pos_std=3.0)
    true_lat, true_lon = _beacon(150.0, 0.0)
    rep_lat, rep_lon = _beacon(170.0, 0.0)
    for _ in range(12):
        _run(f, 10.0, speed=0.0)
        f.gps_update(LAT, LON, 3.0, 0.0)
        r = geodesy.ecef_distance(LAT, LON, -1.0, true_lat, true_lon, -1.0)
        f.range_update(RangeMeas(f.t, f.t, r, "udb", rep_lat, rep_lon, -1.0, -1.0, 1.0, 7.0, 120.0))
    learned = float(f.x[6])
    _run(f, 120.0, speed=0.0)  # one correlation time without ranges
    assert f.x[6] == pytest.approx(learned * math.exp(-1.0), rel=1e-6)
    assert f.P[6, 6] > 0.5 * 7.0**2  # and its uncertainty has grown back towards the prior


def test_re_acquisition_learns_a_current_its_prior_ruled_out() -> None:
    """Re-acquiring widens the current by the drift it implies, not by the (wrong) prior.

    The Chesapeake case: a 0.3 m/s current against a configured 0.01 m/s prior.  Capping
    the widening at the prior would re-acquire the position and then drift off again.
    """
    f = _ekf(pos_std=2.0, noise=NoiseConfig(current_init_std_mps=0.01))
    beacons = [(150.0, 150.0), (-150.0, 100.0), (0.0, -200.0)]
    for k in range(1, 19):  # three minutes, a range every 10 s
        _run(f, 10.0, speed=0.0)
        true_lat, true_lon = geodesy.offset_position(LAT, LON, 0.0, 0.3 * 10.0 * k)
        blat, blon = _beacon(*beacons[k % 3])
        r = geodesy.ecef_distance(true_lat, true_lon, -1.0, blat, blon, -1.0)
        f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1, -1, 1.0))
    assert f.reacquisitions == 1  # once, not again and again as the current drags it off
    assert f.x[3] == pytest.approx(0.3, abs=0.05)  # east current, m/s
    e, n, _ = geodesy.enu_offset(true_lat, true_lon, 0, f.x[0], f.x[1], 0)
    assert math.hypot(e, n) < 10.0


def test_a_multipath_burst_does_not_open_the_gate_to_the_next_outlier() -> None:
    """Three long outliers among good ranges agree on no correction: nothing moves."""
    f = _ekf(pos_std=2.0)
    beacons = [(150.0, 150.0), (-150.0, 100.0), (0.0, -200.0)]
    extra = [0.0, 150.0, 0.0, 10.0, 0.0, 40.0, 30.0]  # metres of multipath on each range
    decisions = []
    for k, x in enumerate(extra):
        blat, blon = _beacon(*beacons[k % 3])
        r = geodesy.ecef_distance(LAT, LON, -1.0, blat, blon, -1.0) + x
        f.t += 10.0
        decisions.append(f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1, -1, 1.0)))
    assert [d.reason for d in decisions[:6]] == ["ok", "gate", "ok", "gate", "ok", "gate"]
    assert f.reacquisitions == 0 and f.reacquire_refused >= 1
    assert not decisions[6].accepted  # the gate still refuses a 30 m outlier
    e, n, _ = geodesy.enu_offset(LAT, LON, 0, f.x[0], f.x[1], 0)
    assert math.hypot(e, n) < 3.0


def test_it_counts_how_often_replies_read_long_past_the_gate() -> None:
    """What a re-acquisition takes as the chance that a run of long replies is a
    reflector's (navd/filter/reacquire.py): one reply in three 100 m long, against none."""
    beacons = [(150.0, 150.0), (-150.0, 100.0), (0.0, -200.0)]

    def fraction(every: int) -> float:
        f = _ekf(pos_std=2.0)
        for k in range(60):
            blat, blon = _beacon(*beacons[k % 3])
            extra = 100.0 if every and k % every == every - 1 else 0.0
            r = geodesy.ecef_distance(LAT, LON, -1.0, blat, blon, -1.0) + extra
            f.t += 10.0
            f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1, -1, 1.0))
        return f.long_refused

    assert fraction(0) == 0.0
    assert fraction(3) == pytest.approx(1.0 / 3.0, abs=0.03)


def test_a_restart_goes_on_counting_long_replies() -> None:
    """A site's reflectors do not leave with the process: the resumed filter starts from
    the checkpoint's counts; counts that cannot be are none."""
    f = _ekf(pos_std=2.0)
    blat, blon = _beacon(150.0, 150.0)
    r = geodesy.ecef_distance(LAT, LON, -1.0, blat, blon, -1.0)
    for k in range(20):
        f.t += 10.0
        long = 100.0 if k % 4 == 3 else 0.0
        f.range_update(RangeMeas(f.t, f.t, r + long, "b", blat, blon, -1, -1, 1.0))
    assert f.long_refused == pytest.approx(0.25, abs=0.03)
    x, P, held = f.checkpoint()
    for counts, expected in (
        (held.long_refused, f.long_refused),
        (None, 0.0),
        ((5.0, 2.0), 0.0),  # more long refusals than ranges
        ((math.nan, 10.0), 0.0),
    ):
        g = _ekf()
        g.restore(x, P, 0.0, Held(held.scale, held.outage, counts))
        assert g.long_refused == pytest.approx(expected)


def test_a_re_acquired_current_carries_the_calibrations_uncertainty() -> None:
    """A filter that started 60 m from where it thought re-acquires while a compass
    reading 10 degrees low drifts its dead reckoning across the track: the fit moves
    only position and current, and reads that drift as a current.  The current it hands
    over must be as uncertain as the calibration that could also explain it, and
    correlated with it, so that later ranges can still move the heading bias rather than
    only the current (navd/filter/ekf_ranges.py)."""
    noise = NoiseConfig(current_init_std_mps=0.01, heading_bias_init_std_deg=10.0)
    f = _ekf(pos_std=2.0, noise=noise)
    beacons = [(150.0, 150.0), (-150.0, 100.0), (0.0, -200.0)]
    speed, bias = 1.5, R(10.0)
    # the fix it started from was 60 m off: the gate refuses the ranges, and the fit
    # finds the position and the drift the compass made
    true_lat, true_lon = geodesy.offset_position(LAT, LON, -60.0, 0.0)
    for k in range(1, 25):
        for _ in range(100):  # 10 s at 10 Hz: the compass says 80, the vehicle runs 90
            f.predict(f.t + 0.1, 0.1, R(90.0) - bias, speed, -1.0)
        true_lat, true_lon = geodesy.offset_position(true_lat, true_lon, 0.0, speed * 10.0)
        blat, blon = geodesy.offset_position(true_lat, true_lon, *beacons[k % 3])
        r = geodesy.ecef_distance(true_lat, true_lon, -1.0, blat, blon, -1.0)
        f.range_update(RangeMeas(f.t, f.t, r, "b", blat, blon, -1, -1, 1.0))
        if f.reacquisitions:
            break
    assert f.reacquisitions == 1
    J = np.array(f.dv_dcal).reshape(2, 2)
    P_cal = f.P[4:6, 4:6]
    # at least the calibration's share of the water-relative velocity's uncertainty ...
    excess = f.P[2:4, 2:4] - J @ P_cal @ J.T
    assert np.all(np.linalg.eigvalsh(excess) > 0.0)
    # ... and correlated with it as the error it may be
    assert np.allclose(f.P[2:4, 4:6], -J @ P_cal)
    assert np.allclose(f.P, f.P.T) and np.all(np.linalg.eigvalsh(f.P) > 0.0)


def test_the_predicted_range_is_its_mean_over_the_filters_uncertainty() -> None:
    """Off the line of sight a range only lengthens: a filter unsure across it must expect
    a longer range than the one from its mean, or it reads every range as long."""
    f = _ekf(pos_std=60.0)
    _run(f, 20.0)
    blat, blon = _beacon(-300.0, 30.0)
    m = RangeMeas(f.t, f.t - 0.4, 0.0, "b", blat, blon, -1.0, -1.0, 1.0)
    first, H = f.predicted_range(m)
    mean, var = f.range_moments(m)
    x0 = f.x.copy()
    rng = np.random.default_rng(7)
    draws = rng.multivariate_normal(np.zeros(N_STATES), f.P, size=10000)
    ranges = []
    for dx in draws:
        f.x = f.state_apply(x0, dx, -1.0)
        ranges.append(f.predicted_range(m)[0])
    f.x = x0
    sampled = float(np.mean(ranges))
    se = float(np.std(ranges)) / math.sqrt(len(ranges))
    assert abs(sampled - first) > 5 * se  # the first-order prediction is short
    assert sampled == pytest.approx(mean, abs=3 * se)
    assert var > float(H @ f.P @ H)
    assert float(np.var(ranges)) == pytest.approx(var, rel=0.1)


def _through_an_outage(as_range_noise: bool) -> tuple[list[float], list[bool]]:
    """Ranges to a boat 800 m north of a vehicle holding its position submerged: reported,
    then predicted through a five-minute outage of the boat's location line, the
    prediction falling behind the boat to 50 m (1.7 times its std) by the end, then
    reported again.  Returns the truth's squared Mahalanobis distance from the estimate
    after each range of the outage and after it, and whether each range after it was
    accepted.  ``as_range_noise``: the extrapolation's error counted as each range's own
    noise, as if it were not shared."""
    f = _ekf(pos_std=2.0)
    vlat, vlon = _beacon(0.0, 0.0)
    true_lat, true_lon = _beacon(800.0, 0.0)
    r = geodesy.ecef_distance(vlat, vlon, -1.0, true_lat, true_lon, -1.0)

    def ranged(reported_north: float, predicted_std: float, since: float) -> bool:
        _run(f, 10.0, speed=0.0)
        rep_lat, rep_lon = _beacon(reported_north, 0.0)
        shared = 0.0 if as_range_noise else predicted_std
        m = RangeMeas(
            f.t,
            f.t,
            r,
            "udb",
            rep_lat,
            rep_lon,
            -1.0,
            -1.0,
            math.hypot(1.0, predicted_std),
            7.0,
            120.0,
            beacon_predicted_std_m=shared,
            beacon_predicted_from=since,
        )
        return f.range_update(m).accepted

    def d2() -> float:
        e, n, _ = geodesy.enu_offset(vlat, vlon, -1.0, float(f.x[0]), float(f.x[1]), -1.0)
        v = np.array([n, e])
        return float(v @ np.linalg.solve(f.P[:2, :2], v))

    for _ in range(12):
        ranged(800.0, 0.0, math.nan)
    t_last = f.t
    seen = []
    for k in range(1, 31):
        ranged(800.0 - 50.0 * k / 30, 1.0 * k, t_last)
        seen.append(d2())
    after = []
    for _ in range(6):
        after.append(ranged(800.0, 0.0, math.nan))
        seen.append(d2())
    return seen, after


def test_a_predicted_boats_error_is_shared_by_the_replies_of_its_outage() -> None:
    """Thirty replies to one extrapolated boat share its error.  Counted as each reply's
    own, they average it away, and the vehicle claims to know where it is from a boat that
    was not there (with a larger error, the reports' return then reads as ranges to
    refuse: a mission of the Monte Carlo's, seed 244, ended 439 m off that way)."""
    d2, after = _through_an_outage(as_range_noise=False)
    chi2_95 = 5.99  # two degrees of freedom
    assert max(d2) < chi2_95
    assert all(after)
    d2_old, _ = _through_an_outage(as_range_noise=True)
    assert max(d2_old) > 9.21  # outside the 99 % ellipse: the old count is misled


def test_a_prediction_from_a_newer_report_starts_a_new_outage() -> None:
    """What the offset learnt of one extrapolation is not the next one's error: a boat
    predicted from a newer report is a new outage, its offset resumed from before the
    first and its variance grown from there by the new prediction's alone."""
    f = _ekf(pos_std=2.0)
    blat, blon = _beacon(800.0, 0.0)
    r = geodesy.ecef_distance(*_beacon(0.0, 0.0), -1.0, blat, blon, -1.0)

    def ranged(predicted_std: float, since: float) -> None:
        _run(f, 10.0, speed=0.0)
        std = math.hypot(1.0, predicted_std)
        f.range_update(
            RangeMeas(
                f.t,
                f.t,
                r,
                "udb",
                blat,
                blon,
                -1.0,
                -1.0,
                std,
                7.0,
                120.0,
                beacon_predicted_std_m=predicted_std,
                beacon_predicted_from=since,
            )
        )

    ranged(0.0, math.nan)
    for k in range(1, 6):
        ranged(20.0 * k, 5.0)  # up to 100 m: across the line of sight nothing learns it
    assert f.P[7, 7] > 50.0**2
    ranged(3.0, 57.0)  # a newer report, 3 m of prediction error
    assert f.P[7, 7] < 7.0**2 + 3.0**2 + 1.0


def _reply(f: RangeEKF, r: float, north: float, predicted_std: float, since: float) -> None:
    """A reply 10 s on to the boat 800 m north, told to be at ``north``, predicted with
    ``predicted_std`` from the report at ``since`` (0 and NaN: reported)."""
    _run(f, 10.0, speed=0.0)
    blat, blon = _beacon(north, 0.0)
    std = math.hypot(1.0, predicted_std)
    f.range_update(
        RangeMeas(
            f.t, f.t, r, "udb", blat, blon, -1.0, -1.0, std, 7.0, 120.0,
            beacon_predicted_std_m=predicted_std, beacon_predicted_from=since,
        )
    )  # fmt: skip


def _mid_outage(restart: str) -> tuple[list[float], float]:
    """A boat predicted for a minute, its prediction falling 5 m a reply behind it along
    the line of sight; after three replies navd goes on (``restart`` "none"), or restarts
    from its checkpoint (a fresh filter) with the outage ("held") or without it
    ("forgotten"); then the boat reports again.  Returns the across-sight offset std after
    each predicted reply from the restart on, and the along-sight offset's mean after the
    first report."""
    f = _ekf(pos_std=2.0)
    r = geodesy.ecef_distance(*_beacon(0.0, 0.0), -1.0, *_beacon(800.0, 0.0), -1.0)
    for _ in range(6):
        _reply(f, r, 800.0, 0.0, math.nan)
    t_last = f.t
    for k in range(1, 4):
        _reply(f, r, 800.0 - 5.0 * k, 10.0 * k, t_last)
    if restart != "none":
        x, P, held = f.checkpoint()
        assert held.outage is not None
        f, t = RangeEKF(NoiseConfig(), 9.0, 4.0, 3), f.t
        f.initialise(float(x[0]), float(x[1]), 1.0, t)
        f.restore(x, P, 0.0, held if restart == "held" else Held(held.scale))
    stds = []
    for k in range(4, 7):
        _reply(f, r, 800.0 - 5.0 * k, 10.0 * k, t_last)
        stds.append(math.sqrt(f.P[7, 7]))
    _reply(f, r, 800.0, 0.0, math.nan)
    return stds, float(f.x[6])


def test_a_restart_in_the_middle_of_an_outage_resumes_it() -> None:
    """The checkpoint holds the outage under way: after a restart the offset grows with
    the prediction's error as if navd had not stopped, and when the boat reports again
    the offset is what it was before the outage, not what it learnt of the
    extrapolation.  Without it, the restart took the outage to start then and kept the
    extrapolation's error as the boat's once the reports returned."""
    stds, north = _mid_outage("none")
    held, held_north = _mid_outage("held")
    assert stds[0] > 30.0
    assert held == pytest.approx(stds, rel=0.05)
    assert abs(north) < 1.0 and abs(held_north) < 1.0
    _, old_north = _mid_outage("forgotten")
    assert old_north > 5.0  # the prediction's lag kept as the boat's error
