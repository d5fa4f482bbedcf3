"""``make bench-sensitivity``: how a scenario's fixed sensor errors decide filter against DR.

A scenario fixes its compass bias, RPM-map error and the beacon's GPS quality; the
seeds only redraw the noise.  Dead reckoning's error is therefore close to one
number per scenario, and on a short mission its errors can cancel.  This bench
re-runs one scenario (claytor-2 by default) with each of those fixed errors changed
in turn, through the same ``navd replay`` path as ``make bench-accuracy``, so the
table shows which of them the default filter's margin over dead reckoning depends on.
Nothing here changes the filter or its configuration.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from bench.accuracy import replay
from bench.common import report
from navd.analysis.score import score
from navd.formats.truth import read_truth
from navd.hil.scenario import Scenario, load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate


def variants(sc: Scenario) -> list[tuple[str, Scenario]]:
    s, b = sc.sensors, sc.boat
    rep = dataclasses.replace

    def sensors(**kw: float) -> Scenario:
        return rep(sc, sensors=rep(s, **kw))

    return [
        ("as replicated", sc),
        (f"compass bias 0 deg (was {s.compass_bias_deg:g})", sensors(compass_bias_deg=0.0)),
        (
            f"compass bias {-s.compass_bias_deg:g} deg (sign flipped)",
            sensors(compass_bias_deg=-s.compass_bias_deg),
        ),
        (
            "RPM map error of the other sign",
            sensors(rpm_per_mps=2 * _configured_rpm(sc) - s.rpm_per_mps),
        ),
        (
            f"beacon GPS {b.gps_std_m / 2:g} m per axis (was {b.gps_std_m:g})",
            rep(sc, boat=rep(b, gps_std_m=b.gps_std_m / 2)),
        ),
        (
            "beacon position exact (no GPS error, no transducer swing)",
            rep(sc, boat=rep(b, gps_std_m=0.0, swing_m=0.0)),
        ),
    ]


def _configured_rpm(sc: Scenario) -> float:
    """The RPM-to-speed map the crew configured (the scenario's ``config``), else the truth."""
    nav = sc.config.get("navigation")
    speed = nav.get("speed") if isinstance(nav, dict) else None
    rpm = speed.get("rpm_per_mps") if isinstance(speed, dict) else None
    return float(rpm) if isinstance(rpm, int | float) else sc.sensors.rpm_per_mps


def run_one(label: str, sc: Scenario, seed: int, workdir: Path) -> tuple[str, float, float]:
    d = workdir / f"{abs(hash(label))}-{seed}"
    write_mission(simulate(sc, seed), d)
    s = score(replay(d, "default"), read_truth(d / "truth.jsonl"))
    return label, s.dr_rms_m, s.rms_m


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="claytor-2")
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args()
    sc = load_scenario(args.scenario)
    cases = variants(sc)
    seeds = range(1, args.seeds + 1)
    rows: dict[str, list[tuple[float, float]]] = {label: [] for label, _ in cases}
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(os.cpu_count()) as pool:
        futs = [pool.submit(run_one, lab, v, k, Path(tmp)) for lab, v in cases for k in seeds]
        for f in futs:
            label, dr, default = f.result()
            rows[label].append((dr, default))
    lines = [
        f"`{args.scenario}` with one fixed error changed at a time; mean over seeds "
        f"1..{args.seeds}; RMS error over the submerged part, metres.",
        "",
        "| variant | DR rms | default rms | default / DR |",
        "|---|---|---|---|",
    ]
    for label, _ in cases:
        dr = statistics.mean(r[0] for r in rows[label])
        de = statistics.mean(r[1] for r in rows[label])
        lines.append(f"| {label} | {dr:.1f} | {de:.1f} | {de / dr:.2f} |")
    body = "\n".join(lines)
    report(body, args.write, "bench-sensitivity", "Sensitivity")
    return 0


if __name__ == "__main__":
    sys.exit(main())
