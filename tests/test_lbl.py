"""Fixed-array LBL through the same filter: three transponders, two (mirror), seed 004's glider."""

from __future__ import annotations

import math

import pytest
from conftest import mission
from serialised import rows

from navd.analysis.replay import run_navigator
from navd.analysis.score import score
from navd.formats.mlog import MeasurementLog
from navd.hil.bound import matched_config
from navd.hil.sim_cli import mission_config
from navd.records import TravelTime
from navd.settings import config_from_dict, deep_merge


def _run(name: str, seed: int, smooth: bool = False):
    m = mission(name, seed)
    cfg = config_from_dict(mission_config(m))
    out = run_navigator(MeasurementLog({}, m.records, []), cfg, smooth).outputs
    return m, out, score(out, m.truth)


def test_three_transponders_under_two_metres() -> None:
    m, out, s = _run("lbl-3", 1)
    assert {r.beacon for r in m.records if isinstance(r, TravelTime)} == {"t1", "t2", "t3"}
    assert s.rms_m < 2.0
    assert s.accepted > 0.9 * (s.accepted + s.rejected)


@pytest.mark.parametrize("seed", range(1, 11))
def test_two_transponders_never_follow_the_mirror(seed: int) -> None:
    _, _, s = _run("lbl-2", seed)
    # the mirror image across the baseline is hundreds of metres away
    assert s.p95_m < 10.0


def test_seed_004_simulation_converges_and_smoothing_helps() -> None:
    """The smoother is closer than the filter, and its ellipse still holds the truth: it
    keeps what the filter's covariance held beside its chain (the range biases' share;
    without it the truth lay inside the smoothed 95 % ellipse 0.87 of the time)."""
    _, out, filt = _run("seaglider", 1)
    _, _, smooth = _run("seaglider", 1, smooth=True)
    assert filt.rms_m < 3.0 and filt.current_rms_mps < 0.05
    assert smooth.rms_m < filt.rms_m
    assert smooth.inside95 >= 0.9
    ests = [o for o in rows(out) if o["type"] == "estimate" and o["mode"] == "submerged"]
    assert ests[-1]["std_n"] < 3.0 and ests[-1]["std_e"] < 3.0


def test_precise_ranges_do_not_average_away_a_transponders_survey_error() -> None:
    """With ranges as precise as the survey (the bound's own model of the mission: 1 m
    ranges, 0.5 m survey errors, white compass and RPM noise), the transponders whose
    survey error is not a state must not be counted as if each reply's error were new:
    the truth stays inside the 95 % ellipse (0.77 of the time when it was, on 8c39e97).
    Nor is the ellipse many times the error: a net sees the water change in every
    direction, so the tide the uncalibrated belief allows for is in its gains, not a lag
    that grows without bound (the published std was 6 m against errors under 1 m)."""
    inside, wide = [], []
    for seed in range(1, 7):
        m = mission("lbl-3", seed)
        crew = mission_config(m)
        cfg = config_from_dict(deep_merge(crew, matched_config(m, config_from_dict(crew))))
        out = run_navigator(MeasurementLog({}, m.records, []), cfg).outputs
        s = score(out, m.truth)
        assert s.rms_m < 2.0
        inside.append(s.inside95)
        ests = [o for o in rows(out) if o["type"] == "estimate" and o["mode"] == "submerged"]
        std = sum(math.hypot(o["std_n"], o["std_e"]) for o in ests) / len(ests)
        wide.append(std / s.rms_m)
    assert sum(inside) / len(inside) >= 0.9
    assert sum(wide) / len(wide) < 3.0
