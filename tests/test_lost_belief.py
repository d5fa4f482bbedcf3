"""The bank's uncalibrated belief, given up by the ranges, moves to the config belief's
mean (navd/filter/bank.py): the Monte Carlo mission that showed it."""

from __future__ import annotations

from bench.robustness import draw, fly
from navd.analysis.score import score
from navd.filter import bank


def test_a_followed_belief_that_refuses_every_true_reply_is_moved() -> None:
    """Monte Carlo seed 92 (wrong-prior): the surface's fixes refute the config's current
    prior, and the bank follows the uncalibrated filter.  A reply just after the dive,
    short by the boat's GPS wander, moves that filter's speed scale the wrong way by a
    standard deviation; every true reply then reads two of its standard deviations long,
    and the long side of its gate refuses them while the config filter accepts them.
    Without the move it was 188 m off in the mean square, with the truth inside the 95 %
    ellipse 0.90 of the time; the bound is 16 m."""
    moved: list[float] = []
    original = bank.CalibrationBank._move_uncal

    def spy(self: bank.CalibrationBank) -> None:
        moved.append(self.config.t)
        original(self)

    bank.CalibrationBank._move_uncal = spy  # type: ignore[method-assign]
    try:
        out, err, truth = fly(draw(92))
    finally:
        bank.CalibrationBank._move_uncal = original  # type: ignore[method-assign]
    assert err == ""
    assert moved and moved[0] < 300.0  # within four minutes of the dive
    s = score(out, truth)
    assert s.rms_m < 60.0
    assert s.inside95 >= 0.9
    assert s.ok_inside99 >= 0.97
