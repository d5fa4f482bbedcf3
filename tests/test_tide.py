"""A crew's tidal prediction (navd/filter/tide.py): the stream it gives, the clock it
needs, the config that states it, and the filter that follows it."""

from __future__ import annotations

import copy
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.common import replay_mission
from bench.robustness import CLASSES, draw, tide_prediction, write_flown
from navd import geodesy
from navd.analysis.score import score
from navd.filter import Navigator
from navd.filter.ekf import RangeEKF
from navd.filter.tide import TidePrediction
from navd.formats.mlog import log_epoch
from navd.formats.truth import read_truth
from navd.records import Clock
from navd.settings import ConfigError, NoiseConfig, TideConfig, config_from_dict
from navd.utc import utc_seconds

FLOOD = "2016-04-14T15:20:00Z"
FLOOD_S = 1460647200.0  # the same instant, seconds since the Unix epoch


def _tide(amplitude: float = 0.8, toward: float = 30.0, period: float = 3600.0) -> TidePrediction:
    tp = TidePrediction.from_config(TideConfig(amplitude, toward, FLOOD, period))
    assert tp is not None
    return tp


def test_a_prediction_is_the_configured_stream_at_its_times() -> None:
    tp = _tide()
    assert tp.velocity(0.0) is None  # no clock yet: no prediction
    tp.offset_s = FLOOD_S - 100.0  # filter time 100 s is the maximum flood
    th = math.radians(30.0)
    assert tp.velocity(100.0) == pytest.approx((0.8 * math.cos(th), 0.8 * math.sin(th)))
    assert tp.velocity(100.0 + 1800.0) == pytest.approx((-0.8 * math.cos(th), -0.8 * math.sin(th)))
    assert tp.velocity(100.0 + 900.0) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert TidePrediction.from_config(TideConfig()) is None  # no amplitude: none


def test_a_filter_carries_the_predicted_change_of_its_current() -> None:
    tp = _tide()
    tp.offset_s = FLOOD_S  # filter time 0 is the maximum flood
    with_tide = RangeEKF(NoiseConfig(), 9.0, 4.0, 3)
    with_tide.tide = tp
    still = RangeEKF(NoiseConfig(), 9.0, 4.0, 3)
    for f in (with_tide, still):
        f.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
    # the prediction is the current's prior mean
    assert with_tide.x[2:4] == pytest.approx(tp.velocity(0.0))
    still.x[2:4] = with_tide.x[2:4]
    dt, steps = 0.1, 6000  # ten minutes, a sixth of this stream's period
    for k in range(1, steps + 1):
        for f in (with_tide, still):
            f.predict(k * dt, dt, 0.3, 1.2, 0.0)
    v_last = tp.velocity((steps - 0.5) * dt)
    assert v_last is not None
    assert with_tide.x[2:4] == pytest.approx(v_last, abs=1e-12)
    # the vehicle drifted by the stream's integral, against a filter that held the
    # flood's current all along
    th = math.radians(30.0)
    w = 2.0 * math.pi / 3600.0
    t1 = steps * dt
    along = 0.8 * (math.sin(w * t1) / w - t1)
    got_e, got_n = _offset_m(still, with_tide)
    assert (got_n, got_e) == pytest.approx((along * math.cos(th), along * math.sin(th)), abs=0.05)
    # a net's twin is a deep copy, and shares the one prediction and its clock
    assert copy.deepcopy(with_tide).tide is tp


def test_a_restart_takes_its_checkpoint_s_current_as_it_is() -> None:
    tp = _tide()
    tp.offset_s = FLOOD_S
    f = RangeEKF(NoiseConfig(), 9.0, 4.0, 3)
    f.tide = tp
    f.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
    for k in range(1, 11):
        f.predict(0.1 * k, 0.1, 0.3, 1.2, 0.0)
    x, P, held = f.checkpoint()
    g = RangeEKF(NoiseConfig(), 9.0, 4.0, 3)
    g.tide = tp
    g.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 60.0)
    g.restore(x, P, 0.0, held)
    g.predict(60.1, 0.1, 0.3, 1.2, 0.0)  # a minute later: no jump of the minute's change
    assert g.x[2:4] == pytest.approx(x[2:4], abs=1e-12)
    g.predict(60.2, 0.1, 0.3, 1.2, 0.0)  # and the stream's change from then on
    a, b = tp.velocity(60.05), tp.velocity(60.15)
    assert a is not None and b is not None
    assert g.x[2:4] - x[2:4] == pytest.approx(np.subtract(b, a), abs=1e-12)


def _offset_m(a: RangeEKF, b: RangeEKF) -> tuple[float, float]:
    e, n, _ = geodesy.enu_offset(a.x[0], a.x[1], 0.0, b.x[0], b.x[1], 0.0)
    return e, n


def _nav_with_tide() -> Navigator:
    cfg = config_from_dict(
        {"navigation": {"tide": {"amplitude_mps": 0.5, "toward_deg": 90, "max_flood_utc": FLOOD}}}
    )
    return Navigator(cfg)


def test_the_navigator_gives_every_filter_of_a_run_the_one_clock() -> None:
    nav = _nav_with_tide()
    nav.set_clock(FLOOD_S)
    tide = nav.tide
    assert tide is not None and tide.velocity(0.0) == pytest.approx((0.0, 0.5), abs=1e-12)
    nav.restart("command")  # fresh filters keep the prediction and its clock
    assert nav.filter.config.tide is tide  # type: ignore[attr-defined]
    assert nav.filter.uncal.tide is tide  # type: ignore[attr-defined]
    nav.set_clock(math.nan)  # a clock that cannot be: the prediction waits
    assert tide.velocity(0.0) is None
    thesis = Navigator(config_from_dict({"navigation": {"filter": "thesis"}}))
    thesis.set_clock(FLOOD_S)  # no prediction configured: nothing to set


def test_the_config_names_a_tide_without_its_time() -> None:
    for when in ("", "2016-04-14T15:20:00", "tomorrow", "2016-13-01T00:00:00Z"):
        tide = {"amplitude_mps": 0.5, "max_flood_utc": when}
        with pytest.raises(ConfigError) as exc:
            config_from_dict({"navigation": {"tide": tide}})
        msg = str(exc.value)
        assert "navigation.tide.max_flood_utc" in msg and "\n" not in msg
    config_from_dict({"navigation": {"tide": {"amplitude_mps": 0.5, "max_flood_utc": FLOOD}}})
    config_from_dict({"navigation": {"tide": {"toward_deg": 10.0}}})  # no amplitude: no time
    with pytest.raises(ConfigError) as exc:  # a value that is no time at all, however long
        config_from_dict({"navigation": {"tide": {"max_flood_utc": "x" * 100_000}}})
    assert "navigation.tide.max_flood_utc" in str(exc.value) and len(str(exc.value)) < 300


def test_a_log_says_its_clock() -> None:
    assert log_epoch({"start_utc": FLOOD}) == FLOOD_S  # the simulator's: t from its start
    daemon = {"start_utc": FLOOD, "time_base": "monotonic", "start_monotonic": 5000.0}
    assert log_epoch(daemon) == FLOOD_S - 5000.0
    assert log_epoch({}) is None
    assert log_epoch({"start_utc": "2016-04-14T15:20:00"}) is None  # no zone
    assert log_epoch({**daemon, "start_monotonic": True}) is None
    assert log_epoch({**daemon, "start_monotonic": "5000"}) is None


@given(st.one_of(st.text(max_size=80), st.integers(), st.none(), st.floats()))
def test_reading_a_utc_time_is_total(text: object) -> None:
    s = utc_seconds(text)
    assert s is None or math.isfinite(s)


def test_a_crew_s_prediction_brings_a_turning_stream_s_mission_nearer() -> None:
    """The first turning tidal stream of the Monte Carlo's draws, replayed with and without
    its crew's prediction (off by as much as bench.robustness draws it)."""
    seed = next(s for s in range(1, 400) if draw(s).cls == "tidal-turning")
    assert "tidal-turning" in CLASSES
    rms = []
    for dr in (draw(seed), tide_prediction(draw(seed))):
        with tempfile.TemporaryDirectory() as td:
            d = Path(td) / "m"
            write_flown(dr, d, None, None)
            out, err = replay_mission(d, "default")
            assert err == ""
            rms.append(score(out, read_truth(d / "truth.jsonl")).rms_m)
    assert rms[1] < 0.8 * rms[0]


def test_the_bank_tests_its_priors_about_the_prediction() -> None:
    """A current that is the predicted flood does not refute a config whose current prior
    is small: the prediction is that prior's mean."""
    from navd.filter.bank import CalibrationBank

    tp = _tide(amplitude=1.0)
    tp.offset_s = FLOOD_S
    followed = RangeEKF(NoiseConfig(current_init_std_mps=0.1), 9.0, 4.0, 3)
    followed.tide = tp
    bank = CalibrationBank(followed)
    bank.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
    assert bank.prior_distance2() == pytest.approx(0.0, abs=1e-18)
    for k in range(1, 601):
        bank.predict(0.1 * k, 0.1, 0.3, 1.2, 0.0)
    assert bank.prior_distance2() < 1e-6  # still the prediction, a minute on
    still = CalibrationBank(RangeEKF(NoiseConfig(current_init_std_mps=0.1), 9.0, 4.0, 3))
    still.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
    still.config.x[2:4] = bank.config.x[2:4]  # the same water, with no prediction of it
    assert still.prior_distance2() > 50.0


def test_given_a_prediction_the_ellipse_allows_only_for_what_it_may_miss() -> None:
    """The uncalibrated belief's ellipse allows for a turning stream as strong as the
    site's strongest; once a prediction is followed, as strong as its stated error."""
    from navd.filter.bank import CalibrationBank, tidal_walk

    def considered_m(tide: TidePrediction | None, clock: bool) -> float:
        f = RangeEKF(NoiseConfig(current_walk_mps_per_sqrt_s=0.0), 9.0, 4.0, 3, 2.0)
        f.tide = tide
        if tide is not None:
            tide.offset_s = FLOOD_S if clock else None
        bank = CalibrationBank(f)
        bank.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
        for k in range(1, 6001):  # ten minutes, no ranges
            bank.predict(0.1 * k, 0.1, 0.3, 1.2, 0.0)
        consider = bank.uncal.consider
        assert consider is not None
        return math.sqrt(consider.covariance(600.0)[0, 0])

    unknown = considered_m(None, False)
    # a walk's position error grows as walk * t^1.5 / sqrt(3)
    assert unknown == pytest.approx(tidal_walk(2.0) * 600.0**1.5 / math.sqrt(3.0), rel=1e-6)
    assert considered_m(_tide(amplitude=0.8), False) == pytest.approx(unknown)  # no clock
    tp = _tide(amplitude=0.8)
    assert considered_m(tp, True) == pytest.approx(unknown * 0.5 * 0.8 / 2.0, rel=1e-6)
    tp.error_fraction = 10.0  # a prediction worse than knowing nothing adds nothing
    assert considered_m(tp, True) == pytest.approx(unknown)


def test_the_config_bounds_a_prediction_s_error() -> None:
    tide = {"amplitude_mps": 0.5, "max_flood_utc": FLOOD}
    cfg = config_from_dict({"navigation": {"tide": {**tide, "error_fraction": 0.3}}})
    tp = TidePrediction.from_config(cfg.navigation.tide)
    assert tp is not None and tp.unknown_mps == pytest.approx(0.15)
    for bad in (0.0, -0.2, 3.0, "half"):
        with pytest.raises(ConfigError) as exc:
            config_from_dict({"navigation": {"tide": {**tide, "error_fraction": bad}}})
        assert "navigation.tide.error_fraction" in str(exc.value) and "\n" not in str(exc.value)


def test_the_receiver_s_utc_sets_a_clock_that_is_off() -> None:
    """The computer's clock starts five hours off (a board with no real-time clock): the
    GPS receiver's UTC is the prediction's clock from its first valid fix; a clock off by
    less than a minute stands."""
    nav = _nav_with_tide()
    tide = nav.tide
    assert tide is not None
    nav.set_clock(FLOOD_S - 5 * 3600.0)
    nav.feed(Clock(10.0, FLOOD_S + 10.0))  # the receiver: t = 0 was the maximum flood
    assert tide.offset_s == pytest.approx(FLOOD_S)
    assert nav.counters["tide_clock_corrected"] == 1
    nav.feed(Clock(70.0, FLOOD_S + 70.0 + 30.0))  # 30 s apart: the clock stands
    assert tide.offset_s == pytest.approx(FLOOD_S) and nav.counters["tide_clock_corrected"] == 1
    nav.feed(Clock(80.0, 1.0e9))  # 2001: a receiver past a week rollover, refused
    assert tide.offset_s == pytest.approx(FLOOD_S) and nav.counters["skipped_implausible"] == 1
    unset = _nav_with_tide()
    unset.feed(Clock(5.0, FLOOD_S + 5.0))  # no clock at all before: the receiver's
    assert unset.tide is not None and unset.tide.offset_s == pytest.approx(FLOOD_S)
    assert unset.counters["tide_clock_from_gps"] == 1


def test_a_clock_set_again_does_not_move_the_current() -> None:
    """The current the data taught stays when the clock is set again; from then on the
    prediction's changes are read on the new clock."""
    tp = _tide()
    tp.offset_s = FLOOD_S - 900.0  # a quarter period off: the stream at its turn
    f = RangeEKF(NoiseConfig(current_walk_mps_per_sqrt_s=0.0), 9.0, 4.0, 3)
    f.tide = tp
    f.initialise(math.radians(37.1), math.radians(-76.4), 5.0, 0.0)
    f.predict(0.1, 0.1, 0.0, 1.0, 0.0)
    taught = f.x[2:4].copy()
    tp.offset_s = FLOOD_S  # the receiver's clock: the maximum flood now
    f.predict(0.2, 0.1, 0.0, 1.0, 0.0)
    assert f.x[2:4] == pytest.approx(taught, abs=1e-12)
    v0 = tp.velocity(0.15)
    f.predict(60.0, 59.8, 0.0, 1.0, 0.0)
    v1 = tp.velocity(60.0 - 0.5 * 59.8)
    assert v0 is not None and v1 is not None
    assert f.x[2:4] == pytest.approx(taught + np.subtract(v1, v0), abs=1e-12)


def test_a_rotated_log_keeps_the_receiver_s_clock_and_a_restart_does_not() -> None:
    """Replay sets each log file's clock; the next file of the same daemon gives the same
    one, and the receiver's correction stands, as it did live.  A restarted daemon (a
    checkpoint's resume) starts again from the computer's clock, as live."""
    from navd.records import Resume

    nav = _nav_with_tide()
    tide = nav.tide
    assert tide is not None
    off = FLOOD_S - 5 * 3600.0
    nav.set_clock(off)
    nav.feed(Clock(10.0, FLOOD_S + 10.0))
    nav.set_clock(off + 0.002)  # the next file's header, rounded
    assert tide.offset_s == pytest.approx(FLOOD_S)
    x = tuple(float(v) for v in nav.filter.x)
    P = tuple(float(v) for v in np.eye(len(x)).ravel())
    nav.feed(Resume(20.0, "default", x, P, 5.0))
    assert tide.offset_s == pytest.approx(off)
