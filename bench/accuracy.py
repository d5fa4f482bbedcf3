"""``make bench-accuracy``: every scenario, several seeds, both filter modes and dead reckoning.

Each mission is simulated, written to disk and run through the ``navd replay``
command line (the public path users take), then scored against the truth.  The
table goes into BENCHMARKS.md between markers, with the command that made it.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from bench.common import mode_config, report
from navd.analysis.score import Score, against_bound, score
from navd.config import load_config
from navd.formats.outputs import read_outputs
from navd.formats.truth import TruthSample, read_truth
from navd.hil.bound import mission_bound
from navd.hil.scenario import list_scenarios, load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.schema import Output, split_outputs


def replay(mission_dir: Path, mode: str, smooth: bool = False) -> list[Output]:
    cfg = mode_config(mission_dir, mode)
    out = mission_dir / f"out-{mode}{'-smooth' if smooth else ''}.jsonl"
    cmd = [
        sys.executable,
        "-m",
        "navd.cli",
        "replay",
        str(mission_dir / "measurements.jsonl"),
        "--config",
        str(cfg),
        "--out",
        str(out),
    ]
    if smooth:
        cmd.append("--smooth")
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return read_outputs(out)


def dvl_errors(mission_dir: Path, truth: list[TruthSample]) -> tuple[float, float, float]:
    """(distance run, actual DVL dead-reckoning error, predicted error) at surfacing."""
    from navd.analysis.score import _ne_error

    est, _ = split_outputs(read_outputs(mission_dir / "out-default.jsonl"))
    by_t = {round(s.t, 3): s for s in truth}
    sub = [o for o in est if o.mode == "submerged"]
    last = sub[-1]
    tr = by_t[round(last.t, 3)]
    dist = 0.0
    prev = None
    for o in sub:
        s = by_t.get(round(o.t, 3))
        if s is not None and prev is not None:
            dist += math.hypot(*_ne_error(s.lat, s.lon, prev.lat, prev.lon))
        prev = s
    if last.dvl_lat is None or last.dvl_lon is None or last.dvl_error_pred_m is None:
        return dist, math.nan, math.nan
    err = math.hypot(*_ne_error(last.dvl_lat, last.dvl_lon, tr.lat, tr.lon))
    return dist, err, last.dvl_error_pred_m


def run_scenario(name: str, seeds: list[int], workdir: Path) -> dict[str, list[Any]]:
    """Scores per mode, and the DVL's (distance, error, predicted error) per seed."""
    sc = load_scenario(name)
    res: dict[str, list[Any]] = {
        "default": [],
        "smoothed": [],
        "thesis": [],
        "vlbl": [],
        "bound": [],
        "against": [],  # the default's ellipses beside the bound's
    }
    for seed in seeds:
        d = workdir / f"{name}-{seed}"
        mission = simulate(sc, seed)
        write_mission(mission, d)
        truth = read_truth(d / "truth.jsonl")
        outs = replay(d, "default")
        # the bound does not model a DVL's velocity: it would not bound that mission
        if not sc.sensors.dvl:
            b = mission_bound(mission, load_config(d / "config.yaml"))
            res["bound"].append(b.rms_m)
            res["against"].append(against_bound(outs, truth, b.ellipses))
        res["default"].append(score(outs, truth))
        res["smoothed"].append(score(replay(d, "default", smooth=True), truth))
        res["thesis"].append(score(replay(d, "thesis"), truth))
        res["vlbl"].append(score(replay(d, "vlbl"), truth))
        if sc.sensors.dvl:
            res.setdefault("dvl", []).append(dvl_errors(d, truth))
    return res


def _m(xs: list[float]) -> float:
    xs = [x for x in xs if not math.isnan(x)]
    return statistics.fmean(xs) if xs else math.nan


def _reacq(d: list[Score]) -> str:
    n = _m([x.reacquisitions for x in d])
    replies = [x.reacquire_replies_max for x in d if not math.isnan(x.reacquire_replies_max)]
    return f"{n:.1f} ({max(replies):.0f})" if replies else f"{n:.1f}"


def _most_replies(results: dict[str, dict[str, list[Any]]]) -> str:
    xs = [
        x.reacquire_replies_max
        for r in results.values()
        for x in r["default"]
        if not math.isnan(x.reacquire_replies_max)
    ]
    return f"{max(xs):.0f}" if xs else "-"


def table(results: dict[str, dict[str, list[Any]]], seeds: list[int]) -> str:
    lines = [
        f"Mean over seeds {seeds[0]}..{seeds[-1]} ({len(seeds)} seeds). Errors in metres over the "
        "submerged part; *surf* = error of the last submerged estimate; *in95* = fraction of "
        "submerged time the truth lies inside the filter's 95 % ellipse; *cur* = RMS current "
        "error (m/s); *acc/rej* = ranges accepted/rejected per mission; *reacq* = re-acquisitions "
        "per mission, and in brackets the most replies any of them took from the first rejection "
        "of its streak to the next accepted range; "
        "*smoothed* = `navd replay --smooth` (RTS): its RMS, and the fraction of submerged time "
        "the truth lies inside its own 95 % ellipse; "
        "*VLBL fix* = the least-squares fix of the virtual net (seed 001; with fixed transponders "
        "the LBL fix of seed 004), published beside the filter, and the fraction of submerged "
        "time it was available.",
        "",
        "| scenario | DR rms | DR surf | thesis rms | thesis surf | thesis acc/rej | default rms "
        "| default p95 | default surf | in95 | cur | acc/rej | reacq | smoothed rms "
        "| smoothed in95 | VLBL fix rms (coverage) | VLBL mode rms |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    tot: dict[str, list[float]] = {
        "dr": [],
        "thesis": [],
        "default": [],
        "smoothed": [],
        "in95": [],
        "smoothed_in95": [],
    }
    for name, r in results.items():
        d, t, s = r["default"], r["thesis"], r["smoothed"]
        row = {
            "dr": _m([x.dr_rms_m for x in d]),
            "thesis": _m([x.rms_m for x in t]),
            "default": _m([x.rms_m for x in d]),
            "smoothed": _m([x.rms_m for x in s]),
            "in95": _m([x.inside95 for x in d]),
            "smoothed_in95": _m([x.inside95 for x in s]),
        }
        for k, v in row.items():
            tot[k].append(v)
        lines.append(
            f"| {name} | {row['dr']:.1f} | {_m([x.dr_surfacing_m for x in d]):.1f} "
            f"| {row['thesis']:.1f} | {_m([x.surfacing_m for x in t]):.1f} "
            f"| {_m([x.accepted for x in t]):.1f}/{_m([x.rejected for x in t]):.1f} "
            f"| {row['default']:.1f} | {_m([x.p95_m for x in d]):.1f} "
            f"| {_m([x.surfacing_m for x in d]):.1f} | {row['in95']:.2f} "
            f"| {_m([x.current_rms_mps for x in d]):.3f} "
            f"| {_m([x.accepted for x in d]):.1f}/{_m([x.rejected for x in d]):.1f} "
            f"| {_reacq(d)} | {row['smoothed']:.1f} | {row['smoothed_in95']:.2f} "
            f"| {_m([x.fix_rms_m for x in d]):.1f} ({_m([x.fix_coverage for x in d]):.0%}) "
            f"| {_m([x.rms_m for x in r['vlbl']]):.1f} |"
        )
    lines.append(
        f"| **suite mean** | {_m(tot['dr']):.1f} | | {_m(tot['thesis']):.1f} | | | "
        f"{_m(tot['default']):.1f} | | | {_m(tot['in95']):.2f} | | | | {_m(tot['smoothed']):.1f} "
        f"| {_m(tot['smoothed_in95']):.2f} | | |"
    )
    ratio = _m(tot["default"]) / _m(tot["thesis"])
    worse_than_thesis = [
        n for n, a, b in zip(results, tot["default"], tot["thesis"], strict=True) if a > b
    ]
    worse_than_dr = [
        n for n, a, b in zip(results, tot["default"], tot["dr"], strict=True) if a > 1.1 * b
    ]
    n_smooth_better = sum(s < f for s, f in zip(tot["smoothed"], tot["default"], strict=True))
    worse_dr = ", ".join(worse_than_dr) or "none"
    lines += [
        "",
        f"- default / thesis mean RMS: **{ratio:.2f}** (target <= 0.5)",
        f"- scenarios where default is worse than thesis: {', '.join(worse_than_thesis) or 'none'}",
        f"- scenarios where default is >10 % worse than dead reckoning: {worse_dr}",
        f"- truth inside the 95 % ellipse, suite mean: {_m(tot['in95']):.2f} (target >= 0.90)",
        f"- smoothed below filtered on {n_smooth_better}/{len(tot['default'])} scenarios; "
        f"truth inside the smoothed 95 % ellipse, suite mean {_m(tot['smoothed_in95']):.2f}, "
        f"least {min(tot['smoothed_in95']):.2f}",
        f"- re-acquisition: at most {_most_replies(results)} replies from the first rejection "
        "to the next accepted range, over every mission",
    ]
    lines += ["", *bound_table(results)]
    dvl_rows = [
        f"| {name} seed {k + 1} | {dist:.0f} | {err:.1f} ({err / dist:.1%}) "
        f"| {pred:.1f} ({pred / dist:.1%}) |"
        for name, r in results.items()
        for k, (dist, err, pred) in enumerate(r.get("dvl", []))
    ]
    if dvl_rows:
        lines += [
            "",
            "DVL dead reckoning against the truth, as seed 002 Table 2 compares it with GPS: "
            "actual error at surfacing and the eq. 14 prediction from the sensors' specified "
            "errors (5 % velocity, 3 deg attitude), absolute and relative to the distance run.",
            "",
            "| mission | distance (m) | actual error (m, %) | predicted (m, %) |",
            "|---|---|---|---|",
            *dvl_rows,
        ]
    return "\n".join(lines)


def _rms(xs: list[float]) -> float:
    xs = [x for x in xs if not math.isnan(x)]
    return math.sqrt(statistics.fmean([x * x for x in xs])) if xs else math.nan


def bound_table(results: dict[str, dict[str, list[Any]]]) -> list[str]:
    """Each scenario against its posterior Cramer-Rao bound (navd/hil/bound.py)."""
    lines = [
        "Against the bound: *bound* = the posterior Cramer-Rao bound of each mission "
        "(navd/hil/bound.py), RMS over the submerged part, mean over the seeds; */ bound* = the "
        "RMS over the seeds of the default's RMS over that of the bound; *ok in99* = while "
        "integrity said ok, the fraction of that time the truth lies inside the 99 % ellipse; "
        "*ok* = the fraction of submerged time integrity said ok; *in95 at bound* = the "
        "fraction of submerged time the truth lies inside a 95 % ellipse of the bound's own "
        "covariance drawn about the estimate (the yardstick for *in95*); *ellipse / bound* = "
        "the RMS over the seeds of the published std over that of the bound's.",
        "",
        "| scenario | default rms | bound | / bound | in95 | in95 at bound | ellipse / bound "
        "| ok in99 | ok |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in results.items():
        d, b, a = r["default"], r["bound"], r["against"]
        ratio = f"{_rms([x.rms_m for x in d]) / _rms(b):.2f}" if b else "n/a"
        bound = f"{_m(b):.1f}" if b else "n/a (DVL)"
        beside = (
            f"{_m([x.inside95 for x in a]):.2f} | "
            f"{_rms([x.published_std_m for x in a]) / _rms([x.bound_std_m for x in a]):.2f}"
            if a
            else "n/a | n/a"
        )
        lines.append(
            f"| {name} | {_m([x.rms_m for x in d]):.1f} | {bound} | {ratio} "
            f"| {_m([x.inside95 for x in d]):.2f} | {beside} "
            f"| {_m([x.ok_inside99 for x in d]):.3f} | {_m([x.ok_fraction for x in d]):.2f} |"
        )
    below = [
        name for name, r in results.items()
        if r["bound"] and _rms([x.rms_m for x in r["default"]]) < _rms(r["bound"])
    ]
    if below:
        lines += [
            "",
            f"Where */ bound* is below 1 ({', '.join(below)}) the bound is not tight for that "
            "scenario: a scenario's calibration errors are fixed and only the noise is redrawn "
            "per seed, while the bound is a mean over priors as large as those errors (an "
            "estimator that knows their size, not their value), and for a tidal stream it "
            "models the current's change as a random walk as fast as the truth's. It is a bound "
            "on the Monte Carlo's mean, where the errors are drawn (bench-robustness), more "
            "than on one fixed mission.",
        ]
    return lines


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--scenarios", nargs="*", help="default: every scenario marked bench: true")
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args()
    names = args.scenarios or [n for n in list_scenarios() if load_scenario(n).bench]
    seeds = list(range(1, args.seeds + 1))
    results = {}
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(os.cpu_count()) as pool:
        futures = {n: pool.submit(run_scenario, n, seeds, Path(tmp)) for n in names}
        for name in names:
            results[name] = futures[name].result()
            print(
                f"{name}: default {_m([s.rms_m for s in results[name]['default']]):.1f} m, "
                f"thesis {_m([s.rms_m for s in results[name]['thesis']]):.1f} m",
                file=sys.stderr,
            )
    body = table(results, seeds)
    report(body, args.write, "bench-accuracy", "Accuracy")
    return 0


if __name__ == "__main__":
    sys.exit(main())
