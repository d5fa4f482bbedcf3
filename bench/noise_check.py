"""Does `navd report`'s test of the noise model tell the truth?

A real mission has no truth to hold its ellipse against; the report judges the noise model
by the accepted ranges' mean NIS instead (navd/analysis/report.py, ``noise_verdict``).
Here each of the Monte Carlo's missions (bench/robustness.py's draws: as drawn, with
every prior 3 to 10 times too small, and with ranges 1.5 to 3 times noisier than the
config says) is replayed, its verdict taken as the report would,
and set beside what the truth says: the error's mean squared Mahalanobis distance in the
published ellipse, per axis (NEES, 1 for an ellipse the size of the error, below 1 wider).

    python -m bench.noise_check --missions 120 [--write BENCHMARKS.md]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from bench.common import report
from bench.robustness import Draw, draw, fly, wide_ranges, wrong_priors
from navd.analysis.jobs import default_jobs, run_all
from navd.analysis.report import noise_verdict
from navd.analysis.score import score
from navd.schema import RangeDecision

# each variant of the draws, by the words its rows go by
VARIANTS: dict[str, Callable[[Draw], Draw]] = {
    "as drawn": lambda dr: dr,
    "with every prior too small": wrong_priors,
    "with ranges noisier than the config says": wide_ranges,
}


@dataclass(frozen=True, slots=True)
class Checked:
    seed: int
    cls: str
    kind: str
    variant: str
    # fits | wider | narrower | unjudged (too few from fixed transponders) | none (too few
    # accepted ranges at all) | error
    verdict: str
    mean_nis: float
    nees: float


def check_one(seed: int, variant: str) -> Checked:
    dr = VARIANTS[variant](draw(seed))
    out, err, truth = fly(dr)
    nan = float("nan")
    if err:
        return Checked(seed, dr.cls, dr.kind, variant, "error", nan, nan)
    v = noise_verdict(o for o in out if isinstance(o, RangeDecision))
    nees = score(out, truth).nees
    if v is None:
        return Checked(seed, dr.cls, dr.kind, variant, "none", nan, nees)
    return Checked(seed, dr.cls, dr.kind, variant, v.verdict, v.mean_nis, nees)


def _row(name: str, rs: list[Checked]) -> str:
    n = len(rs)
    wider = [r for r in rs if r.verdict == "wider"]
    narrower = [r for r in rs if r.verdict == "narrower"]
    fits = [r for r in rs if r.verdict == "fits"]

    def median(xs: list[float]) -> str:
        xs = [x for x in xs if x == x]
        return f"{statistics.median(xs):.2f}" if xs else "-"

    return (
        f"| {name} | {n} | {len(wider)} | {sum(r.nees < 1.0 for r in wider)} | "
        f"{len(narrower)} | {sum(r.nees > 1.0 for r in narrower)} | {len(fits)} | "
        f"{sum(r.verdict in ('unjudged', 'none', 'error') for r in rs)} | "
        f"{median([r.mean_nis for r in rs])} | {median([r.nees for r in rs])} | "
        f"{sum(r.nees > 1.0 for r in rs)} |"
    )


def table(results: list[Checked], missions: int) -> str:
    lines = [
        f"`python -m bench.noise_check --missions {missions}`",
        "",
        f"The {missions} missions of `make bench-robustness`, as drawn, with every "
        "prior 3 to 10 times too small (`--wrong-priors`) and with ranges 1.5 to 3 times "
        "noisier than the config says (`--wide-ranges`), each replayed and judged as "
        "`navd report` judges it, from its accepted ranges' mean NIS alone: *wider* "
        "(below 0.45: the ellipse is likely wider than the error), *narrower* (above 2), "
        "*fits*, or *no verdict* (fewer than 30 accepted ranges from fixed transponders: "
        "a moving beacon's ranges carry its GPS error, which hides the ellipse). Beside "
        "it the truth: *NEES*, the error's mean squared Mahalanobis distance in the "
        "published ellipse per axis over the submerged time (1 for an ellipse the size of"
        " the error). *true* counts the verdicts the truth bears out (NEES below 1 for "
        "*wider*, above 1 for *narrower*); *NEES > 1* counts the missions whose ellipse "
        "was narrower than their error, whatever the verdict.",
        "",
        "| missions | n | wider | true | narrower | true | fits | no verdict | median mean NIS "
        "| median NEES | NEES > 1 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label in VARIANTS:
        rs = [r for r in results if r.variant == label]
        lines.append(_row(f"**{label}**", rs))
        for kind, name in (("beacon", "single beacon"), ("lbl-2", "2-transponder"),
                           ("lbl-3", "3-transponder")):  # fmt: skip
            sub = [r for r in rs if r.kind == kind]
            if sub:
                lines.append(_row(f"{label}: {name}", sub))
    for label in VARIANTS:
        rs = [r for r in results if r.variant == label]
        lines.append("")
        lines.append(f"{label.capitalize()}, where the truth says otherwise:")
        lines.append("")
        for verdict, bad in (
            ("wider", [r for r in rs if r.verdict == "wider" and not r.nees < 1.0]),
            ("narrower", [r for r in rs if r.verdict == "narrower" and not r.nees > 1.0]),
            ("fits, with NEES > 1", [r for r in rs if r.verdict == "fits" and r.nees > 1.0]),
        ):
            seeds = ", ".join(
                f"{r.seed} ({r.cls}, NIS {r.mean_nis:.2f}, NEES {r.nees:.2f})" for r in bad
            )
            lines.append(f"- *{verdict}*: {seeds or 'none'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="bench.noise_check", description=__doc__.split("\n\n")[0])
    p.add_argument("--missions", type=int, default=120)
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--write", help="put the table in this BENCHMARKS.md")
    args = p.parse_args(argv)
    seeds = list(range(1, args.missions + 1))
    t0 = time.perf_counter()
    variants = [v for v in VARIANTS for _ in seeds]
    results = run_all(check_one, seeds * len(VARIANTS), variants, jobs=args.jobs)
    took = time.perf_counter() - t0
    body = table(results, args.missions) + (
        f"\n\nRan in {took / 60:.1f} min on {args.jobs} worker processes."
    )
    report(body, args.write, "bench-noise-check", "The ranges' test of the noise model")
    return 0


if __name__ == "__main__":
    sys.exit(main())
