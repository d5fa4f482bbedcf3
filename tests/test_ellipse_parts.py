"""The ellipse-parts bench measures what it says (bench/ellipse_parts.py): its NEES is the
error's distance in the ellipse, its scale is 1 for an ellipse the size of the error's, and
a mission is sampled at every submerged second, each part a covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.ellipse_parts import CHI2_95, PARTS, Nees, _nees, _row, run_one
from bench.robustness import draw


def test_nees_is_the_squared_distance_in_the_ellipse() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        a = rng.normal(size=(2, 2))
        C = a @ a.T + 0.01 * np.eye(2)
        e = rng.normal(size=2) * 10.0
        want = float(e @ np.linalg.solve(C, e))
        got = _nees((float(e[0]), float(e[1])), C[0, 0], C[1, 1], C[0, 1])
        assert got == pytest.approx(want, rel=1e-9)
    assert _nees((1.0, 0.0), 1.0, 1.0, 1.0) == math.inf  # a line, not an ellipse
    assert _nees((1.0, 0.0), math.nan, 1.0, 0.0) == math.inf


def _cells(row: str) -> list[str]:
    return [c.strip() for c in row.strip("|").split("|")]


@pytest.mark.parametrize("too_wide", [1.0, 2.0])
def test_the_scale_is_how_much_wider_than_the_error_an_ellipse_is(too_wide: float) -> None:
    """Errors drawn from the ellipse itself score k = 1 and 0.95 inside; an ellipse twice
    as wide as the errors' scores k = 1/2."""
    rng = np.random.default_rng(5)
    e = rng.normal(size=(40000, 2))
    nees = (e * e).sum(axis=1) / too_wide**2
    run = Nees("base", {p: nees.tolist() for p in PARTS}, [0.5] * len(nees), [True] * len(nees))
    cells = _cells(_row("base", [run]))
    inside, k = float(cells[3]), float(cells[3 + len(PARTS)])
    ok_inside = float(cells[3 + 2 * len(PARTS)])
    assert k == pytest.approx(1.0 / too_wide, abs=0.02)
    assert inside == pytest.approx(1.0 - math.exp(-CHI2_95 * too_wide**2 / 2.0), abs=0.005)
    assert ok_inside == pytest.approx(1.0 - 0.01 ** (too_wide**2), abs=0.003)


def test_a_mission_s_parts_are_measured_every_submerged_second() -> None:
    seed = next(s for s in range(1, 200) if draw(s).cls == "short-near")
    r = run_one(seed, matched=False, no_outliers=False, wrong=False)
    assert not r.error
    n = len(r.parts["published"])
    assert n > 100 and all(len(v) == n for v in r.parts.values())
    assert len(r.weights) == len(r.ok) == n and any(r.ok)
    assert all(0.0 <= w <= 1.0 for w in r.weights)
    pub = np.array(r.parts["published"])
    assert np.isfinite(pub).all()
    # the blends run from the followed belief's ellipse to the published one
    assert r.blends[0.0] == pytest.approx(r.parts["followed"], rel=1e-9)
    assert r.blends[1.0] == pytest.approx(r.parts["published"], rel=1e-9)
    # the mixture holds the wider uncalibrated belief too, so the error lies nearer its
    # centre than in the followed belief's ellipse alone
    assert np.median(r.parts["+ other belief"]) <= np.median(r.parts["followed"])
