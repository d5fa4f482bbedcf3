"""The posterior Cramér-Rao bound of a simulated mission (navd/hil/bound.py)."""

from __future__ import annotations

import dataclasses
import math

from navd.hil.bound import matched_config, mission_bound
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import crew_config
from navd.hil.world import simulate
from navd.settings import config_from_dict, deep_merge


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


def test_the_matched_config_is_a_valid_config_with_the_bounds_model() -> None:
    """bench.robustness --matched-noise gives navd the bound's own model of a mission: a
    config the config layer takes, with the simulator's sensor noise, and a current walk
    as fast as the truth's current changes."""
    walks = {}
    for name in ("cb1", "tidal"):
        sc = load_scenario(name)
        m = simulate(sc, 1)
        crew = crew_config(sc)
        cfg = config_from_dict(deep_merge(crew, matched_config(m, config_from_dict(crew))))
        nz = cfg.navigation.noise
        assert nz.heading_std_deg == sc.sensors.compass_noise_deg
        assert nz.input_corr_s == 1.0 / sc.sensors.rate_hz
        assert nz.range_std_m >= sc.acoustics.range_noise_m
        assert cfg.beacons["udb"].position_std_m == sc.boat.gps_std_m
        walks[name] = nz.current_walk_mps_per_sqrt_s
        # parts of the model alone (--matched-noise current calibration) leave the crew's
        # other keys
        part = matched_config(m, config_from_dict(crew), ("current", "calibration"))
        one = config_from_dict(deep_merge(crew, part)).navigation
        assert one.noise.current_walk_mps_per_sqrt_s == walks[name]
        assert one.noise.heading_bias_walk_deg_per_sqrt_s == 0.0
        crew_nav = config_from_dict(crew).navigation
        assert one.noise.heading_std_deg == crew_nav.noise.heading_std_deg
        assert one.noise.range_std_m == crew_nav.noise.range_std_m
        assert one.sound_speed == crew_nav.sound_speed
        assert one.noise.heading_std_deg != nz.heading_std_deg
    assert walks["cb1"] < 0.1 * walks["tidal"]


def test_the_bound_keeps_its_ellipse_at_every_submerged_step() -> None:
    """Each class's published ellipse is set beside these (bench-robustness): one per
    submerged step, in time order, positive definite, and together the bound's RMS."""
    sc = load_scenario("claytor-2")
    m = simulate(sc, 1)
    b = mission_bound(m, config_from_dict(crew_config(sc)))
    assert len(b.ellipses) == b.steps > 0
    ts = [e[0] for e in b.ellipses]
    assert ts == sorted(ts)
    assert all(vn > 0.0 and ve > 0.0 and c * c < vn * ve for _, vn, ve, c in b.ellipses)
    mean_var = sum(vn + ve for _, vn, ve, _ in b.ellipses) / b.steps
    assert math.isclose(math.sqrt(mean_var), b.rms_m)
