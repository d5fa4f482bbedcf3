"""The Monte Carlo's draws (bench/robustness.py): what its options change, and what not."""

from __future__ import annotations

import math

import pytest

from bench.robustness import (
    NOISE_DRAW_STRIDE,
    TIDE_DIRECTION_ERR_DEG,
    TIDE_SPEED_ERR,
    TIDE_TIME_ERR_S,
    draw,
    noise_seed,
    tide_prediction,
    wrong_priors,
)
from navd.filter.tide import TidePrediction
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import crew_config
from navd.hil.world import current_at
from navd.settings import config_from_dict
from navd.utc import utc_seconds


def test_wrong_priors_tell_every_class_three_to_ten_times_less_than_its_errors() -> None:
    """``--wrong-priors`` asks whether a class's geometry stays honest when the config's
    priors are too small, as the wrong-prior class draws them: each prior is 3 to 10 times
    smaller than the mission's own error, and nothing else of the mission changes."""
    seen = set()
    for seed in range(1, 80):
        dr = draw(seed)
        wr = wrong_priors(dr)
        if dr.cls == "wrong-prior":
            assert wr == dr
            continue
        seen.add(dr.cls)
        sc = dr.scenario
        noise = wr.scenario["config"]["navigation"]["noise"]
        cur = sc["current"]["speed_mps"] + sc["current"].get("tidal_amplitude_mps", 0.0)
        bias = abs(sc["sensors"]["compass_bias_deg"])
        scale = abs(
            sc["config"]["navigation"]["speed"]["rpm_per_mps"] / sc["sensors"]["rpm_per_mps"] - 1
        )
        for error, floor, prior in (
            (cur / 2**0.5, 0.05 / 2**0.5, noise["current_init_std_mps"]),
            (bias, 0.5, noise["heading_bias_init_std_deg"]),
            (scale, 0.01, noise["speed_scale_init_std"]),
        ):
            assert 2.9 <= max(error, floor) / prior <= 10.1
        # the rest of the mission, and its own config, as drawn
        assert {k: v for k, v in wr.scenario.items() if k != "config"} == {
            k: v for k, v in sc.items() if k != "config"
        }
        rest = {k: v for k, v in wr.scenario["config"]["navigation"].items() if k != "noise"}
        assert rest == {k: v for k, v in sc["config"]["navigation"].items() if k != "noise"}
        assert (wr.seed, wr.cls, wr.kind, wr.outliers) == (dr.seed, dr.cls, dr.kind, dr.outliers)
    assert {"base", "short-near", "boat-outage"} <= seen


def test_every_other_draw_of_noise_has_its_own_stream() -> None:
    """``--noise-draw K`` reruns the same conditions with other noise: draw 0 is the mission
    as drawn (its own seed), and no other draw of any mission shares a noise seed with a
    mission or with another draw."""
    seeds = range(1, 1001)
    assert all(noise_seed(s, 0) is None for s in seeds)
    others = [noise_seed(s, k) for k in range(1, 6) for s in seeds]
    assert len(set(others)) == len(others)
    assert not set(others) & set(seeds)
    with pytest.raises(ValueError):
        noise_seed(NOISE_DRAW_STRIDE, 1)


def test_a_crew_s_tidal_prediction_is_its_mission_s_stream_within_the_errors_drawn() -> None:
    """``--tide-prediction`` gives the crew of a mission with a tide its stream, off by no
    more than the bench draws: the filter's prediction at the flood it names is the
    simulator's stream half an hour either side, and nothing else of the mission changes."""
    tidal = 0
    for seed in range(1, 120):
        dr = draw(seed)
        tp = tide_prediction(dr)
        if dr.scenario["current"].get("tidal_amplitude_mps", 0.0) <= 0.0:
            assert tp == dr
            continue
        tidal += 1
        sc = scenario_from_dict(tp.scenario)
        cfg = config_from_dict(crew_config(sc))
        pred = TidePrediction.from_config(cfg.navigation.tide)
        assert pred is not None
        start = utc_seconds(sc.start_utc)
        assert start is not None
        pred.offset_s = start  # the simulator's log: t = 0 at its start
        amp = sc.current.tidal_amplitude_mps
        assert abs(pred.amplitude_mps / amp - 1.0) <= TIDE_SPEED_ERR + 1e-3
        turn = (math.degrees(pred.toward_rad) - sc.current.toward_deg + 180.0) % 360.0 - 180.0
        assert abs(turn) <= TIDE_DIRECTION_ERR_DEG + 0.1
        # the predicted flood: the truth's own flood lies within the time error of it
        t_flood = pred.flood_utc_s - start
        err_s = round(TIDE_TIME_ERR_S)
        best = max(
            (current_at(sc, t_flood + dt) for dt in range(-err_s, err_s + 1, 30)),
            key=lambda v: v[0] * math.cos(pred.toward_rad) + v[1] * math.sin(pred.toward_rad),
        )
        assert math.hypot(*best) == pytest.approx(amp + sc.current.speed_mps, rel=0.01)
        assert {k: v for k, v in tp.scenario.items() if k != "config"} == {
            k: v for k, v in dr.scenario.items() if k != "config"
        }
    assert tidal >= 10


def test_the_monte_carlo_can_start_past_the_missions_it_has_flown() -> None:
    """``--from`` flies seeds not flown before, each exactly as a run from seed 1 draws it."""
    from bench.robustness import selected

    assert selected(700, None, None, first=401) == list(range(401, 701))
    tidal = selected(700, "tidal-turning", None, first=401)
    assert tidal and all(s >= 401 and draw(s).cls == "tidal-turning" for s in tidal)
    assert tidal == [s for s in selected(700, "tidal-turning", None) if s >= 401]
