"""The Monte Carlo's draws (bench/robustness.py): what its options change, and what not."""

from __future__ import annotations

import pytest

from bench.robustness import NOISE_DRAW_STRIDE, draw, noise_seed, wrong_priors


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
