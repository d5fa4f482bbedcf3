"""`navd report`'s test of the noise model by the accepted ranges' NIS, against the truth:
when it says the published ellipse is wider than the error, it is."""

from __future__ import annotations

import tempfile
from pathlib import Path

from bench.common import replay_mission
from bench.robustness import draw
from navd.analysis.report import ReportInput, summary
from navd.analysis.score import score
from navd.formats.truth import read_truth
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.schema import Estimate, RangeDecision


def test_a_net_flown_with_ranges_quieter_than_configured_is_told_its_ellipse_is_too_wide() -> None:
    """Monte Carlo seed 1: three surveyed transponders, whose replies carry 1 m of noise
    against the config's 3 m.  The truth lies inside the 95 % ellipse all the time; the
    report, which has no truth, says so from the ranges alone."""
    dr = draw(1)
    assert dr.kind == "lbl-3"
    with tempfile.TemporaryDirectory() as td:
        d = Path(td) / "m"
        write_mission(simulate(scenario_from_dict(dr.scenario), 1), d, None)
        truth = read_truth(d / "truth.jsonl")
        out, err = replay_mission(d, "default")
    assert err == ""
    est = [o for o in out if isinstance(o, Estimate)]
    dec = [o for o in out if isinstance(o, RangeDecision)]
    line = next(x for x in summary(ReportInput(est, dec, [], [])) if "NIS" in x)
    assert "wider than the error" in line
    s = score(out, truth)
    assert s.inside95 > 0.99  # what the line claimed, seen with the truth
