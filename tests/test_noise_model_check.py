"""`navd report`'s test of the noise model by the accepted ranges' NIS, against the truth:
when it says the published ellipse is wider than the error, it is."""

from __future__ import annotations

from bench.robustness import draw, fly
from navd.analysis.report import ReportInput, summary
from navd.analysis.score import score
from navd.schema import Estimate, RangeDecision


def test_a_net_flown_with_ranges_quieter_than_configured_is_told_its_ellipse_is_too_wide() -> None:
    """Monte Carlo seed 1: three surveyed transponders, whose replies carry 1 m of noise
    against the config's 3 m.  The truth lies inside the 95 % ellipse all the time; the
    report, which has no truth, says so from the ranges alone."""
    dr = draw(1)
    assert dr.kind == "lbl-3"
    out, err, truth = fly(dr)
    assert err == ""
    est = [o for o in out if isinstance(o, Estimate)]
    dec = [o for o in out if isinstance(o, RangeDecision)]
    line = next(x for x in summary(ReportInput(est, dec, [], [])) if "NIS" in x)
    assert "wider than the error" in line
    s = score(out, truth)
    assert s.inside95 > 0.99  # what the line claimed, seen with the truth
