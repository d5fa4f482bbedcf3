"""The attainability bench measures what it says: its measurements are the bound's model, its
reference filter is consistent on them, and its full-information estimate is the solve it
claims to be (bench/attainable.py)."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from bench.attainable import Generated, Model, Tide, ekf, generate, navd_core, smooth
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


def test_the_tide_s_form_moves_the_vehicle_by_its_integral() -> None:
    """The constituent states carry the vehicle by the integral of a cos(wt) + b sin(wt), and
    their Jacobian columns are those integrals; with none of the bound's walk left, the mean
    current no longer walks."""
    _, _, g, _ = _mission(_BEACON)
    tide = Tide(0.3, omega=2.0 * math.pi / 40000.0, walk_share=0.0)
    model = Model(g, 1.0, tide)
    c = model.tide_col
    assert model.n == g.P0.shape[0] + 4
    assert np.allclose(model.P0[c:, c:], 0.09 * np.eye(4))
    x = np.zeros(model.n)
    x[c : c + 4] = 0.2, -0.1, 0.05, 0.3  # a north, a east, b north, b east
    ka, kb = 100, 1100
    moved, F, Q = model.transition(ka, kb, x)
    still, _, _ = model.transition(ka, kb, np.zeros(model.n))
    # by the midpoint rule, not the closed form the model uses
    h = (kb - ka) * g.dt / 200000
    t = ka * g.dt + h * (np.arange(200000) + 0.5)
    cos_int = float(np.sum(np.cos(tide.omega * t)) * h)
    sin_int = float(np.sum(np.sin(tide.omega * t)) * h)
    want = (0.2 * cos_int + 0.05 * sin_int, -0.1 * cos_int + 0.3 * sin_int)
    assert moved[0:2] - still[0:2] == pytest.approx(want, rel=1e-6)
    assert F[0, c] == pytest.approx(cos_int, rel=1e-6)
    assert F[1, c + 3] == pytest.approx(sin_int, rel=1e-6)
    assert np.all(Q[2:4, 2:4] == 0.0)
    assert np.all(Q[c:, c:] == 0.0)


def test_a_crew_s_tide_is_sized_from_the_mission_s_own() -> None:
    m, _, _, _ = _mission(_BEACON)
    assert Tide.for_mission(m, 1.0, None) is None  # this mission's water has no tide
    tidal = next(s for s in range(1, 200) if draw(s).cls == "tidal-turning")
    mt = simulate(scenario_from_dict(draw(tidal).scenario), tidal)
    amp = mt.scenario.current.tidal_amplitude_mps
    one = Tide.for_mission(mt, 1.0, None)
    assert one is not None and one.std_mps == pytest.approx(amp / math.sqrt(2.0))
    wide = Tide.for_mission(mt, 1.5, None)
    assert wide is not None and wide.std_mps == pytest.approx(1.5 * one.std_mps)
    site = Tide.for_mission(mt, None, 1.41)
    assert site is not None and site.std_mps == 1.41
    # a prior for water whose tide nobody predicted is flown where there is none too
    assert Tide.for_mission(m, None, 0.35) is None
    anywhere = Tide.for_mission(m, None, 0.35, everywhere=True, walk_share=0.25)
    assert anywhere is not None and (anywhere.std_mps, anywhere.walk_share) == (0.35, 0.25)
    assert Tide.for_mission(m, 1.0, None, everywhere=True) is None  # no amplitude to scale
