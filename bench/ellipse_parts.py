"""What the default mode's published ellipse is made of, class by class.

The default mode publishes one covariance (navd/filter/bank.py): the followed belief's
own, widened by two hedges.  The other belief (the config's priors, or those priors
widened to an uncalibrated vehicle's) takes its share of the mixture, and the
uncalibrated belief carries a tide that may turn faster than its walk (the considered
tide, navd/filter/consider.py).  A net of two transponders adds the other crossing of
their circles (navd/filter/mirror.py).  Where the published ellipse is wider than the
error, this bench says which part makes it so.

For each Monte Carlo mission (bench/robustness.py's draws), once a second of submerged
time (a tick fed with a range is skipped: the bank has fused the range by the time the
tick's estimate is read), the error's normalised squared distance (NEES, two degrees of
freedom) is taken against three covariances about the published mean:

* *followed*: the followed belief alone (its filter's covariance and its range biases'
  share);
* *+ other belief*: the mixture of both beliefs with the weight navd draws its ellipse
  with, neither carrying the considered tide;
* *published*: what navd publishes, the considered tide and any other crossing added.

Reported per class: the fraction of that time the truth lies inside each one's 95 %
ellipse, and the scale ``k`` by which each would have to be multiplied (as a standard
deviation) for the truth to lie inside its 95 % ellipse 0.95 of the time,
``sqrt(q95(NEES) / chi2_2(0.95))``: below 1 the part is wider than the error, above 1
narrower; and, while integrity said ``ok``, the fraction of that time the truth lies
inside each one's 99 % ellipse.  *weight* is the mean weight of the belief that is not
followed.  Each figure pools the sampled seconds of the class's missions, so a long mission
counts for more (bench/robustness.py's class figures are means over missions).

A second table blends the two: the followed belief's covariance plus a share of the
hedges (published less followed), so that one can read how much of them each class's
figures need (bench/ellipse_scan.py asks it of both targets at once).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.common import mode_config, report
from bench.robustness import CLASSES, selected, variant, write_flown
from navd import geodesy
from navd.analysis.jobs import default_jobs, run_all
from navd.config import load_config
from navd.filter.bank import CalibrationBank, switched
from navd.filter.common import StateEstimate, spread_about
from navd.filter.ekf import RangeEKF
from navd.filter.navigator import Navigator
from navd.formats.mlog import MeasurementStream
from navd.formats.truth import read_truth
from navd.hil.bound import MATCHED_PARTS
from navd.schema import Estimate, RangeDecision

#: chi-square on two degrees of freedom at 0.95 and 0.99: the 95 % and 99 % ellipses
CHI2_95 = -2.0 * math.log(0.05)
CHI2_99 = -2.0 * math.log(0.01)
PARTS = ("followed", "+ other belief", "published")
GEOMETRIES = ("lbl-2", "lbl-3")
#: how much of the hedges (published less followed) a blended ellipse keeps
BLENDS = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass
class Nees:
    """The NEES of each part at each sampled instant of one mission, and the weights."""

    group: str
    parts: dict[str, list[float]] = field(default_factory=lambda: {p: [] for p in PARTS})
    weights: list[float] = field(default_factory=list)
    ok: list[bool] = field(default_factory=list)  # integrity said ok
    error: str = ""
    # the NEES against followed + a * (published - followed), for each a of BLENDS
    blends: dict[float, list[float]] = field(default_factory=lambda: {a: [] for a in BLENDS})


def _nees(e: tuple[float, float], nn: float, ee: float, ne: float) -> float:
    """``e^T C^-1 e`` for C = [[nn, ne], [ne, ee]]; infinite where C is not an ellipse."""
    det = nn * ee - ne * ne
    if not (det > 0.0 and math.isfinite(det)):
        return math.inf
    n, east = e
    return (ee * n * n - 2.0 * ne * n * east + nn * east * east) / det


def _own(f: RangeEKF) -> StateEstimate:
    """A belief's estimate without the considered tide."""
    s = f.estimate()
    if f.consider is None:
        return s
    nn, ee, ne = f.consider.position(f.t)
    return StateEstimate(
        s.lat, s.lon, s.current_n, s.current_e, s.var_n - nn, s.var_e - ee, s.cov_ne - ne
    )


def _parts(bank: CalibrationBank, o: Estimate) -> dict[str, tuple[float, float, float]]:
    a, b = _own(bank.config), _own(bank.uncal)
    w = switched(bank.w_uncal)
    if bank.refuted:
        a, b, w = b, a, 1.0 - w
    mixed = spread_about(a, b, w)
    return {
        "followed": (a.var_n, a.var_e, a.cov_ne),
        "+ other belief": (mixed.var_n, mixed.var_e, mixed.cov_ne),
        "published": (o.std_n**2, o.std_e**2, o.cov_ne),
    }


def run_one(seed: int, matched: bool, no_outliers: bool, wrong: bool, wide: bool = False) -> Nees:
    """Mission ``seed`` replayed by the default mode, its NEES by part once a second."""
    dr = variant(seed, no_outliers, wrong, wide)
    out = Nees(dr.cls if dr.kind == "beacon" else dr.kind)
    with tempfile.TemporaryDirectory(prefix="navd-parts-") as td:
        d = Path(td) / "m"
        write_flown(dr, d, None, tuple(MATCHED_PARTS) if matched else None)
        truth = {round(s.t, 1): s for s in read_truth(d / "truth.jsonl")}
        nav = Navigator(load_config(mode_config(d, "default")))
        bank = nav.filter
        if not isinstance(bank, CalibrationBank):
            out.error = f"the default mode runs {type(bank).__name__}, not the bank"
            return out
        last = -math.inf
        for rec in MeasurementStream(d / "measurements.jsonl"):
            outs = nav.feed(rec, True)
            if any(isinstance(o, RangeDecision) for o in outs):
                # the bank has fused that range since the ticks before it were published
                continue
            for o in outs:
                if not isinstance(o, Estimate) or o.mode != "submerged" or o.t < last + 1.0:
                    continue
                s = truth.get(round(o.t, 1))
                if s is None:
                    continue
                last = o.t
                e = geodesy.nearby_offset(
                    math.radians(s.lat),
                    math.radians(s.lon),
                    math.radians(o.lat),
                    math.radians(o.lon),
                )
                parts = _parts(bank, o)
                for name, cov in parts.items():
                    out.parts[name].append(_nees(e, *cov))
                own, pub = parts["followed"], parts["published"]
                for a in BLENDS:
                    blend = (x + a * (y - x) for x, y in zip(own, pub, strict=True))
                    out.blends[a].append(_nees(e, *blend))
                w = switched(bank.w_uncal)
                out.weights.append(1.0 - w if bank.refuted else w)
                out.ok.append(o.integrity == "ok")
    return out


def groups(runs: Sequence[Nees]) -> list[tuple[str, list[Nees]]]:
    """The runs by class (a net of the base class is its geometry's row, not base's), then
    all of them; runs that failed are left out."""
    good = [r for r in runs if not r.error]
    out = [(g, [r for r in good if r.group == g]) for g in [*CLASSES, *GEOMETRIES]]
    return [(g, mine) for g, mine in out if mine] + [("**all**", good)]


def _figures(v: np.ndarray, ok: np.ndarray) -> tuple[float, float]:
    """In the 95 % ellipse, and while ``ok`` in the 99 % ellipse, of NEES ``v``."""
    inside = float(np.mean(v <= CHI2_95))
    return inside, float(np.mean(v[ok] <= CHI2_99)) if ok.any() else math.nan


def _row(name: str, runs: Sequence[Nees]) -> str:
    cells = [name, str(len(runs))]
    w = [x for r in runs for x in r.weights]
    cells.append(f"{np.mean(w):.2f}" if w else "-")
    ok = np.array([x for r in runs for x in r.ok], dtype=bool)
    inside, scale, ok_inside = [], [], []
    for p in PARTS:
        v = np.array([x for r in runs for x in r.parts[p]])
        if not len(v):
            inside.append("-")
            scale.append("-")
            ok_inside.append("-")
            continue
        v_in, v_ok = _figures(v, ok)
        inside.append(f"{v_in:.3f}")
        scale.append(f"{math.sqrt(float(np.quantile(v, 0.95)) / CHI2_95):.2f}")
        ok_inside.append("-" if math.isnan(v_ok) else f"{v_ok:.3f}")
    return "| " + " | ".join(cells + inside + scale + ok_inside) + " |"


def table(runs: Sequence[Nees]) -> str:
    head = (
        "| class | missions | weight | "
        + " | ".join(f"in95 {p}" for p in PARTS)
        + " | "
        + " | ".join(f"k {p}" for p in PARTS)
        + " | "
        + " | ".join(f"ok in99 {p}" for p in PARTS)
        + " |"
    )
    lines = [head, "|" + "---|" * (3 + 3 * len(PARTS))]
    lines += [_row(g, mine) for g, mine in groups(runs)]
    return "\n".join(lines)


def blend_figures(runs: Sequence[Nees], a: float, s: float = 1.0) -> tuple[float, float]:
    """In95, and ok in99, of the followed ellipse plus ``a`` of the hedges, its standard
    deviations scaled by ``s``; nan where nothing was sampled (or never ``ok``)."""
    v = np.array([x for r in runs for x in r.blends[a]]) / (s * s)
    ok = np.array([x for r in runs for x in r.ok], dtype=bool)
    if not len(v):
        return math.nan, math.nan
    return _figures(v, ok)


def _blend_cell(runs: Sequence[Nees], a: float) -> str:
    inside, ok_inside = blend_figures(runs, a)
    if math.isnan(inside):
        return "-"
    return f"{inside:.3f} / " + ("-" if math.isnan(ok_inside) else f"{ok_inside:.3f}")


def blends(runs: Sequence[Nees]) -> str:
    """Per class, in95 and ok in99 of the followed belief's ellipse with each share of the
    hedges added (0: the followed belief alone, 1: the published ellipse)."""
    lines = [
        "| class | " + " | ".join(f"hedges x {a:g}" for a in BLENDS) + " |",
        "|" + "---|" * (1 + len(BLENDS)),
    ]
    for g, mine in groups(runs):
        lines.append(f"| {g} | " + " | ".join(_blend_cell(mine, a) for a in BLENDS) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--missions", type=int, default=120, help="seeds 1..N")
    p.add_argument("--only", choices=list(CLASSES), help="of those, this class's")
    p.add_argument("--kind", choices=["beacon", *GEOMETRIES], help="of those, this geometry's")
    p.add_argument(
        "--matched-noise",
        action="store_true",
        help="navd given the bound's own model of each mission",
    )
    p.add_argument("--no-outliers", action="store_true", help="no multipath, no corrupt positions")
    p.add_argument("--wrong-priors", action="store_true", help="every class's priors too small")
    p.add_argument(
        "--wide-ranges",
        action="store_true",
        help="every mission's ranges 1.5 to 3 times noisier than the config's range_std_m",
    )
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args(argv)
    seeds = selected(args.missions, args.only, args.kind)
    n = len(seeds)
    t0 = time.perf_counter()
    runs = run_all(
        run_one,
        seeds,
        [args.matched_noise] * n,
        [args.no_outliers] * n,
        [args.wrong_priors] * n,
        [args.wide_ranges] * n,
        jobs=args.jobs,
    )
    took = (time.perf_counter() - t0) / 60.0
    failed = [f"seed {s}: {r.error}" for s, r in zip(seeds, runs, strict=True) if r.error]
    command = (
        f"python -m bench.ellipse_parts --missions {args.missions}"
        + (f" --only {args.only}" if args.only else "")
        + (f" --kind {args.kind}" if args.kind else "")
        + (" --matched-noise" if args.matched_noise else "")
        + (" --no-outliers" if args.no_outliers else "")
        + (" --wrong-priors" if args.wrong_priors else "")
        + (" --wide-ranges" if args.wide_ranges else "")
    )
    body = (
        f"`{command}`\n\n{table(runs)}\n\n"
        "In the 95 % ellipse / while `ok` in the 99 % ellipse, with a share of the hedges "
        "(published less followed) added to the followed belief's:\n\n"
        f"{blends(runs)}\n\n"
        + ("".join(f"{f}\n" for f in failed) + "\n" if failed else "")
        + f"Ran in {took:.1f} min on {args.jobs} worker processes."
    )
    report(body, args.write, "bench-ellipse-parts", "The published ellipse by its parts")


if __name__ == "__main__":
    main()
