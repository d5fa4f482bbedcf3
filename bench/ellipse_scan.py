"""Whether any one width of the published ellipse meets the issue's two ellipse targets in a class.

Issue 22 asks, in every class, for the truth inside the 95 % ellipse between 0.90 and
0.99 of the time, and inside the 99 % ellipse at least 0.97 of the time integrity says
``ok``: both as drawn and with every prior too small (``--wrong-priors``).  The default
mode's ellipse is the followed belief's widened by two hedges (bench/ellipse_parts.py).
This bench asks whether some other width would meet all four figures in a class: the
followed belief's covariance plus a share ``a`` of the hedges (0 none, 1 all of them),
the whole multiplied by ``s`` squared (``s`` a scale of the standard deviations).

Every mission of the class is flown twice by the default mode (as drawn, and with every
prior too small) and sampled as bench/ellipse_parts.py samples it, once a second of
submerged time; for each ``(a, s)`` of the grid the four figures are recomputed from the
same errors.  Integrity's ``ok`` is held as navd gave it: it follows the ranges'
innovations and the ellipse's size, so another width would move it a little too.

Reported per class: the four figures of the published ellipse (``a`` = 1, ``s`` = 1), and
for each share the scales that meet all four; the last row, the pairs that meet them in
every class at once.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

from bench.common import report
from bench.ellipse_parts import BLENDS, Nees, groups, run_one
from bench.ellipse_parts import blend_figures as figures
from bench.robustness import CLASSES, selected
from navd.analysis.jobs import default_jobs, run_all

SCALES = tuple(round(0.5 + 0.1 * i, 1) for i in range(9))  # 0.5 .. 1.3
IN95 = (0.90, 0.99)
OK99 = 0.97


def meets(drawn: Sequence[Nees], wrong: Sequence[Nees], a: float, s: float) -> bool:
    """All four figures within the issue's targets (a figure with no samples fails)."""
    for runs in (drawn, wrong):
        inside, ok_inside = figures(runs, a, s)
        if not (IN95[0] <= inside <= IN95[1] and ok_inside >= OK99):
            return False
    return True


def _scales(ss: Sequence[float]) -> str:
    """``0.8-1.0`` for a run of grid steps, ``0.6, 0.9`` for steps apart."""
    parts: list[list[float]] = []
    for s in ss:
        if parts and round(s - parts[-1][-1], 1) == 0.1:
            parts[-1].append(s)
        else:
            parts.append([s])
    return ", ".join(f"{p[0]:.1f}" if len(p) == 1 else f"{p[0]:.1f}-{p[-1]:.1f}" for p in parts)


def feasible(drawn: Sequence[Nees], wrong: Sequence[Nees]) -> dict[float, list[float]]:
    """For each share of the hedges, the scales that meet all four figures."""
    return {a: [s for s in SCALES if meets(drawn, wrong, a, s)] for a in BLENDS}


def table(drawn: Sequence[Nees], wrong: Sequence[Nees]) -> str:
    lines = [
        "| class | missions | as drawn: in95 / ok in99 | priors too small: in95 / ok in99 | "
        + " | ".join(f"scales that meet all four, hedges x {a:g}" for a in BLENDS)
        + " |",
        "|" + "---|" * (4 + len(BLENDS)),
    ]
    every: set[tuple[float, float]] | None = None
    wrong_by = dict(groups(wrong))
    for g, d in groups(drawn):
        w = wrong_by.get(g, [])
        if g == "**all**" or not w:
            continue
        ok = feasible(d, w)
        pairs = {(a, s) for a, ss in ok.items() for s in ss}
        every = pairs if every is None else every & pairs
        cells = [g, str(len(d))]
        for runs in (d, w):
            inside, ok_inside = figures(runs, 1.0, 1.0)
            cells.append(f"{inside:.3f} / {ok_inside:.3f}")
        cells += [_scales(ok[a]) or "none" for a in BLENDS]
        lines.append("| " + " | ".join(cells) + " |")
    if every is not None:
        cells = ["**every class**", "", "", ""]
        cells += [_scales(sorted(s for b, s in every if b == a)) or "none" for a in BLENDS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def at(drawn: Sequence[Nees], wrong: Sequence[Nees], a: float, s: float) -> str:
    """The four figures of one width, class by class."""
    lines = [
        f"At hedges x {a:g}, scale {s:g}:\n",
        "| class | as drawn: in95 / ok in99 | priors too small: in95 / ok in99 |",
        "|---|---|---|",
    ]
    wrong_by = dict(groups(wrong))
    for g, d in groups(drawn):
        cells = [g]
        for runs in (d, wrong_by.get(g, [])):
            inside, ok_inside = figures(runs, a, s)
            cells.append(f"{inside:.3f} / {ok_inside:.3f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--missions", type=int, default=120, help="seeds 1..N")
    p.add_argument("--only", choices=list(CLASSES), help="of those, this class's")
    p.add_argument(
        "--at",
        nargs=2,
        type=float,
        action="append",
        default=[],
        metavar=("SHARE", "SCALE"),
        help="also print the four figures of this width by class (repeatable)",
    )
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args(argv)
    seeds = selected(args.missions, args.only, None)
    n = len(seeds)
    t0 = time.perf_counter()
    flown = {
        wrong: run_all(
            run_one, seeds, [False] * n, [False] * n, [wrong] * n, [False] * n, jobs=args.jobs
        )
        for wrong in (False, True)
    }
    took = (time.perf_counter() - t0) / 60.0
    failed = [
        f"seed {s}: {r.error}"
        for runs in flown.values()
        for s, r in zip(seeds, runs, strict=True)
        if r.error
    ]
    command = (
        f"python -m bench.ellipse_scan --missions {args.missions}"
        + (f" --only {args.only}" if args.only else "")
        + "".join(f" --at {a:g} {s:g}" for a, s in args.at)
    )
    body = (
        f"`{command}`\n\n{table(flown[False], flown[True])}\n\n"
        + "".join(f"{at(flown[False], flown[True], a, s)}\n\n" for a, s in args.at)
        + ("".join(f"{f}\n" for f in failed) + "\n" if failed else "")
        + f"Ran in {took:.1f} min on {args.jobs} worker processes."
    )
    title = "Whether one width of the ellipse meets both targets"
    report(body, args.write, "bench-ellipse-scan", title)


if __name__ == "__main__":
    main()
