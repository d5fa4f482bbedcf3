"""``make bench-files``: replay and export of a mutated one-hour log, against the clean one.

Simulates the ``survey-1h`` scenario (3,700 s, 111,000 records), then times the whole
``navd replay`` and ``navd export --csv`` commands on the clean log and on mutated
copies (navd/hil/mutate.py, the property test's mutations): one of each kind in the
middle of the log, the far time jumps that once cost a mission, and random draws of
one to four mutations.  Each mutated run must finish within twice the clean run's
time and lose no more records than the lines the mutations touched plus the
16-line hold window each.
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import report
from navd.formats.mlog import HOLD_LINES, read_measurement_log
from navd.hil.mutate import JUMPS, KINDS, Mutation, mutate
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate


def _time(cmd: list[str], runs: int) -> float:
    best = float("inf")
    for _ in range(runs):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t0)
        if r.returncode != 0:
            raise RuntimeError(r.stderr.strip().splitlines()[-1] if r.stderr else "failed")
    return best


def _commands(log: Path, cfg: Path, out: Path) -> dict[str, list[str]]:
    navd = [sys.executable, "-m", "navd.cli"]
    return {
        "replay": [*navd, "replay", str(log), "--config", str(cfg), "--out", str(out)],
        "export": [*navd, "export", str(log), "--config", str(cfg), "--csv", str(out)],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument("--random", type=int, default=8, help="random mutation draws")
    p.add_argument("--runs", type=int, default=2, help="runs of each command (best taken)")
    args = p.parse_args()
    rng = random.Random(1)
    cases: list[tuple[str, list[Mutation]]] = [
        (kind, [(kind, 0.5, 0x7B if kind == "flip" else 0, 1e9)]) for kind in KINDS
    ]
    cases += [
        ("two lines 10^6 s ahead", [("time", 0.4, 0, 1e6), ("time", 0.4 + 1e-5, 0, 1e6)]),
        ("a line at t = -10^9", [("time", 0.6, 0, -1e9)]),
    ]
    for k in range(args.random):
        muts = [
            (rng.choice(KINDS), rng.random(), rng.randrange(256), rng.choice(JUMPS))
            for _ in range(rng.randint(1, 4))
        ]
        cases.append((f"random {k + 1}: " + ", ".join(m[0] for m in muts), muts))
    with tempfile.TemporaryDirectory(prefix="navd-files-") as tmp:
        d = Path(tmp)
        write_mission(simulate(load_scenario("survey-1h"), 1), d)
        clean_log = d / "measurements.jsonl"
        text = clean_log.read_text()
        header, body = text.split("\n", 1)
        lines = body.splitlines(keepends=True)
        cfg = d / "config.yaml"
        clean_records = read_measurement_log(clean_log).records
        base = {
            name: _time(cmd, args.runs)
            for name, cmd in _commands(clean_log, cfg, d / "out").items()
        }
        rows = []
        worst = 0.0
        for label, muts in cases:
            data, touched = mutate(lines, muts)
            log = d / "mutated.jsonl"
            log.write_bytes(header.encode() + b"\n" + data)
            times = {
                name: _time(cmd, args.runs) for name, cmd in _commands(log, cfg, d / "out").items()
            }
            kept = {(type(r).__name__, r.t) for r in read_measurement_log(log).records}
            lost = sum(1 for r in clean_records if (type(r).__name__, r.t) not in kept)
            allowed = touched + HOLD_LINES * len(muts)
            ratio = max(times[n] / base[n] for n in times)
            worst = max(worst, ratio)
            verdict = "ok" if ratio <= 2.0 and lost <= allowed else "**no**"
            rows.append(
                f"| {label} | {times['replay']:.2f} | {times['export']:.2f} | {ratio:.2f} | "
                f"{touched} | {lost} | {verdict} |"
            )
    out = [
        f"One-hour mission (`survey-1h`, seed 1, {len(clean_records)} records); the whole "
        f"commands, best of {args.runs} runs. Clean log: `navd replay` {base['replay']:.2f} s, "
        f"`navd export --csv` {base['export']:.2f} s.",
        "",
        "| mutation | replay (s) | export (s) | worst / clean | lines touched | records lost "
        "| within 2x and the hold window |",
        "|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Worst ratio to the clean log: {worst:.2f} (target: at most 2). Records lost are those "
        "of the clean log missing from the mutated one's; allowed: the lines touched plus "
        f"{HOLD_LINES} (the hold window) per mutation (a truncation touches every line after "
        "its cut).",
    ]
    report("\n".join(out), args.write, "bench-files", "Mutated logs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
