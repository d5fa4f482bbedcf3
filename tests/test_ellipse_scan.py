"""The ellipse-width scan finds the widths that meet the issue's ellipse targets, and only
those (bench/ellipse_scan.py)."""

from __future__ import annotations

import numpy as np

from bench.ellipse_parts import BLENDS, Nees, blend_figures
from bench.ellipse_scan import _scales, at, feasible, meets, table


def _runs(group: str, wider: float, n: int = 20000, seed: int = 0) -> list[Nees]:
    """Errors drawn from a unit normal, against an ellipse ``wider`` times the error's (as a
    standard deviation) at every share of the hedges; integrity ``ok`` throughout."""
    e = np.random.default_rng(seed).standard_normal((n, 2))
    nees = (np.sum(e * e, axis=1) / wider**2).tolist()
    r = Nees(group)
    r.blends = {a: list(nees) for a in BLENDS}
    r.ok = [True] * n
    return [r]


def test_a_right_ellipse_scores_its_own_probabilities() -> None:
    inside, ok_inside = blend_figures(_runs("base", 1.0), 1.0, 1.0)
    assert abs(inside - 0.95) < 0.005
    assert abs(ok_inside - 0.99) < 0.003
    # half the width holds the truth where chi-square(2) <= 5.99 / 4: 1 - exp(-0.75)
    inside, _ = blend_figures(_runs("base", 1.0), 1.0, 0.5)
    assert abs(inside - (1.0 - np.exp(-0.75))) < 0.01


def test_an_ellipse_too_wide_as_drawn_and_right_with_wrong_priors_has_no_width() -> None:
    """Twice too wide as drawn asks s <= 0.62 for the ceiling; right with the priors too
    small asks s >= 0.88 for the floor: no one scale meets both."""
    drawn, wrong = _runs("base", 2.0), _runs("base", 1.0, seed=1)
    assert not any(meets(drawn, wrong, 1.0, s) for s in np.arange(0.3, 1.5, 0.01))
    assert all(not ss for ss in feasible(drawn, wrong).values())
    # each alone has its widths: scaled, the too-wide one is right
    assert meets(drawn, drawn, 1.0, 0.5)
    assert meets(wrong, wrong, 1.0, 1.0)
    assert not meets(wrong, wrong, 1.0, 0.7)


def test_the_every_class_row_is_what_all_classes_share() -> None:
    drawn = _runs("base", 1.0) + _runs("lbl-3", 2.0, seed=2)
    wrong = _runs("base", 1.0, seed=3) + _runs("lbl-3", 2.0, seed=4)
    rows = {line.split(" | ")[0].strip("| "): line for line in table(drawn, wrong).splitlines()}
    # a right ellipse meets them from 0.9 to 1.2 (s >= 0.88 for the floor, <= 1.24 for the
    # ceiling); one twice too wide at half its width and a little more
    assert rows["base"].endswith("| 0.9-1.2 |") and rows["lbl-3"].endswith("| 0.5-0.6 |")
    assert rows["**every class**"].endswith("| none | none | none | none | none |")


def test_scales_are_written_as_runs_of_the_grid() -> None:
    assert _scales([0.8, 0.9, 1.0]) == "0.8-1.0"
    assert _scales([0.5, 0.7, 0.8]) == "0.5, 0.7-0.8"
    assert _scales([]) == ""


def test_one_width_s_figures_are_those_of_each_variant_by_class() -> None:
    drawn = _runs("base", 2.0) + _runs("lbl-3", 1.0, seed=2)
    wrong = _runs("base", 1.0, seed=3) + _runs("lbl-3", 1.0, seed=4)
    lines = at(drawn, wrong, 1.0, 0.5).splitlines()
    rows = {line.split(" | ")[0].strip("| "): line for line in lines if line.startswith("| ")}
    for g in ("base", "lbl-3"):
        d = blend_figures([r for r in drawn if r.group == g], 1.0, 0.5)
        w = blend_figures([r for r in wrong if r.group == g], 1.0, 0.5)
        assert rows[g] == f"| {g} | {d[0]:.3f} / {d[1]:.3f} | {w[0]:.3f} / {w[1]:.3f} |"
    # twice too wide as drawn, base is right at half its width
    assert abs(blend_figures(drawn[:1], 1.0, 0.5)[0] - 0.95) < 0.005
    assert rows["**all**"].startswith("| **all** | ")
