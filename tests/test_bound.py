"""The posterior Cramér-Rao bound of a simulated mission (navd/hil/bound.py)."""

from __future__ import annotations

import dataclasses
import math

from navd.hil.bound import mission_bound
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import crew_config
from navd.hil.world import simulate
from navd.settings import config_from_dict


def _bound(sc, seed: int = 1) -> float:
    m = simulate(sc, seed)
    return mission_bound(m, config_from_dict(crew_config(sc))).rms_m


def test_the_bound_grows_with_range_noise_and_with_fewer_ranges() -> None:
    sc = load_scenario("claytor-2")
    base = _bound(sc)
    assert math.isfinite(base) and base > 0.0
    noisy = dataclasses.replace(
        sc, acoustics=dataclasses.replace(sc.acoustics, range_noise_m=10.0)
    )
    assert _bound(noisy) > base
    sparse = dataclasses.replace(
        sc, acoustics=dataclasses.replace(sc.acoustics, ping_interval_s=40.0)
    )
    assert _bound(sparse) > base


def test_fixed_transponders_bound_below_a_single_moving_beacon() -> None:
    assert _bound(load_scenario("lbl-3")) < 0.5 * _bound(load_scenario("cb1"))


def test_the_ideal_detector_keeps_only_clean_replies() -> None:
    sc = load_scenario("multipath")
    m = simulate(sc, 2)
    b = mission_bound(m, config_from_dict(crew_config(sc)))
    assert 0 < b.ranges == len(m.channel.clean) < m.replies
