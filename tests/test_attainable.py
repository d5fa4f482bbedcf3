"""The attainability bench measures what it says: its measurements are the bound's model, its
reference filter is consistent on them, and its full-information estimate is the solve it
claims to be (bench/attainable.py)."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from bench.attainable import Generated, Model, ekf, generate, navd_core, smooth
from bench.robustness import draw
from navd.hil.bound import matched_config, range_variance
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import mission_config
from navd.hil.world import Mission, simulate
from navd.settings import Config, config_from_dict, deep_merge

# seed 1 of the Monte Carlo is a 3-transponder net, seed 4 a single moving beacon
_NET, _BEACON = 1, 4


def _mission(seed: int) -> tuple[Mission, Config, Generated, Model]:
    m = simulate(scenario_from_dict(draw(seed).scenario), seed)
    cfg = config_from_dict(mission_config(m))
    g = generate(m, cfg, np.random.default_rng([seed, 0]))
    assert g is not None
    return m, cfg, g, Model(g, range_variance(m))


@pytest.mark.parametrize("seed", [_NET, _BEACON])
def test_the_ranges_drawn_are_the_bound_model_s_at_the_truth(seed: int) -> None:
    _, _, g, model = _mission(seed)
    res = []
    for nd in g.nodes:
        if nd.ranges:
            z, hx, _, _ = model.measurements(nd, g.truth_x[nd.k])
            res.extend((z[-len(nd.ranges) :] - hx[-len(nd.ranges) :]) / math.sqrt(model.r_var))
    assert len(res) > 30
    assert abs(statistics.fmean(res)) < 4.0 / math.sqrt(len(res))
    assert 0.7 < statistics.fmean([r * r for r in res]) < 1.4


@pytest.mark.parametrize("seed", [_NET, _BEACON])
def test_the_reference_filter_is_consistent_on_the_bound_s_model(seed: int) -> None:
    """A Jacobian of the wrong sign (a beacon's position error added where it is taken away)
    left the net's filter ten sigmas off with a mean NIS of 2.9; this holds it at 1."""
    _, _, g, model = _mission(seed)
    nis: list[float] = []
    ekf(model, nis)
    assert 0.7 < statistics.fmean(nis) < 1.4


def test_the_full_information_estimate_is_a_converged_solve() -> None:
    _, _, g, model = _mission(_NET)
    traj = ekf(model)
    for _ in range(3):
        traj, _P = smooth(model, g.nodes, traj)
    again, _P = smooth(model, g.nodes, traj)
    moved = max(float(np.max(np.abs(a[0:2] - b[0:2]))) for a, b in zip(again, traj, strict=True))
    assert moved < 1e-3
    # and it uses what the filter could not: over the whole mission, nearer the truth
    err = [
        float(np.hypot(*(x[0:2] - g.truth_x[nd.k, 0:2])))
        for x, nd in zip(traj, g.nodes, strict=True)
    ]
    err_f = [
        float(np.hypot(*(x[0:2] - g.truth_x[nd.k, 0:2])))
        for x, nd in zip(ekf(model), g.nodes, strict=True)
    ]
    assert statistics.fmean(err) < statistics.fmean(err_f)


def test_navd_on_the_bound_s_model_of_a_net_is_near_the_bound_and_honest() -> None:
    m, cfg, g, model = _mission(_NET)
    matched = config_from_dict(deep_merge(mission_config(m), matched_config(m, cfg)))
    out = navd_core(g, matched, math.sqrt(model.r_var))
    scored = [nd for nd in g.nodes if nd.scored]
    assert len(out) == len(scored) > 10
    err2 = [
        float(np.sum((ne - g.truth_x[nd.k, 0:2]) ** 2))
        for (ne, _), nd in zip(out, scored, strict=True)
    ]
    bound2 = [g.bound_var[nd.k] for nd in scored]
    assert math.sqrt(statistics.fmean(err2)) < 1.6 * math.sqrt(statistics.fmean(bound2))
    inside = [
        float(d @ np.linalg.solve(cov, d)) <= 5.991
        for (ne, cov), nd in zip(out, scored, strict=True)
        for d in [ne - g.truth_x[nd.k, 0:2]]
    ]
    assert statistics.fmean(inside) >= 0.9
