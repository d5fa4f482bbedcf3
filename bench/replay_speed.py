"""``make bench-replay``: how fast ``navd replay`` runs a one-hour mission.

Simulates the ``survey-1h`` scenario (3,700 s, 10 Hz sensors, a ping every 10 s),
then times the ``navd replay`` command end to end (process start, reading and
parsing the log, filtering, writing the output), best of three.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import mode_config, report
from navd.formats import jsonlines
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument("--runs", type=int, default=3)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        write_mission(simulate(load_scenario("survey-1h"), 1), d)
        n_lines = sum(1 for _ in (d / "measurements.jsonl").open()) - 1
        rows = []
        for mode, smooth in (("default", False), ("thesis", False), ("default", True)):
            cfg = mode_config(d, mode)
            cmd = [
                sys.executable,
                "-m",
                "navd.cli",
                "replay",
                str(d / "measurements.jsonl"),
                "--config",
                str(cfg),
                "--out",
                str(d / "out.jsonl"),
            ]
            if smooth:
                cmd.append("--smooth")
            best = float("inf")
            for _ in range(args.runs):
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                best = min(best, time.perf_counter() - t0)
            out = jsonlines.read(d / "out.jsonl")
            steps = sum(1 for o in out if o["type"] == "estimate")
            ranges = sum(1 for o in out if o["type"] == "range")
            label = mode + (" + RTS smoother" if smooth else "")
            rows.append(f"| {label} | {n_lines} | {steps} | {ranges} | {best:.2f} |")
    body = "\n".join(
        [
            f"One-hour mission (`survey-1h`, seed 1), best of {args.runs} runs of the whole "
            "`navd replay` command.",
            "",
            "| mode | log records | filter steps out | ranges | wall time (s) |",
            "|---|---|---|---|---|",
            *rows,
            "",
            "Target: under 5 s for 36,000 filter steps and 360 pings.",
        ]
    )
    report(body, args.write, "bench-replay", "Replay speed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
