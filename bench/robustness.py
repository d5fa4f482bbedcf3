"""``make bench-robustness``: a Monte Carlo of missions over randomly drawn conditions.

One fixed draw of sensor errors can favour dead reckoning or flatter the filter
(BENCHMARKS.md, sensitivity), so every mission here draws its own: outlier rate
and length, drops in bursts, corrupted beacon positions, compass bias, RPM-map
error, current (often across the track and more than half the vehicle's speed),
a boat anchored, drifting or motoring, a beacon 50 m to 2 km away, 10 to 60
minutes, and the single moving beacon or 2- and 3-transponder LBL.  Seeds are a
fixed list, so the table is reproducible; none of the bundled scenarios is used.

Each mission goes through the ``navd replay`` command line in the default and
thesis modes (dead reckoning comes with the default output) and is scored against
the simulator's truth.  A divergence is a final error above max(100 m, 2 x the
thesis mode's final error) or an RMS current error above 0.5 m/s.
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.common import mode_config, report
from navd.analysis.score import Score, read_jsonl, score
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate

DIVERGED_FINAL_M = 100.0
DIVERGED_CURRENT_MPS = 0.5


@dataclass(frozen=True, slots=True)
class Draw:
    seed: int
    kind: str  # beacon, lbl-2, lbl-3
    outliers: float
    drops: float
    cross_current: bool  # across the track and faster than half the vehicle's speed
    scenario: dict[str, Any]


def draw(seed: int) -> Draw:
    """The conditions of mission ``seed``: every error drawn, none chosen."""
    rng = random.Random(seed)
    kind = rng.choices(["beacon", "lbl-2", "lbl-3"], weights=[3, 1, 1])[0]
    speed = rng.uniform(1.0, 2.0)
    duration = rng.uniform(600.0, 3600.0)
    heading = rng.uniform(0.0, 360.0)
    pattern = rng.choice(["straight", "lawnmower", "random"])
    legs, t = [], 0.0
    k = 0
    while t < duration:
        d = min(duration - t, rng.uniform(60.0, 400.0))
        if pattern == "straight":
            h = heading + rng.uniform(-10.0, 10.0)
        elif pattern == "lawnmower":
            h = heading + (180.0 if k % 2 else 0.0)
        else:
            h = rng.uniform(0.0, 360.0)
        legs.append({"heading_deg": round(h % 360.0, 1), "duration_s": round(d, 1)})
        t += d
        k += 1
    cur_speed = rng.uniform(0.0, 1.0)
    cur_dir = rng.uniform(0.0, 360.0)
    across = abs(math.sin(math.radians(cur_dir - heading)))
    outliers = rng.uniform(0.0, 0.5)
    drops = rng.uniform(0.0, 0.5)
    corrupt = rng.uniform(0.0, 0.1)
    rpm_true = rng.uniform(850.0, 1000.0)
    rpm_err = rng.uniform(-0.12, 0.12)
    sc: dict[str, Any] = {
        "name": f"mc-{seed}",
        "description": "Monte Carlo draw (bench/robustness.py)",
        "bench": False,
        "vehicle": {
            "lat": round(rng.uniform(-60.0, 60.0), 4),
            "lon": round(rng.uniform(-179.0, 179.0), 4),
            "speed_mps": round(speed, 2),
            "depth_m": round(rng.uniform(2.0, 20.0), 1),
            "legs": legs,
        },
        "current": {"speed_mps": round(cur_speed, 3), "toward_deg": round(cur_dir, 1)},
        "sensors": {
            "declination_deg": round(rng.uniform(-20.0, 20.0), 1),
            "compass_bias_deg": round(rng.uniform(-6.0, 6.0), 2),
            "rpm_per_mps": round(rpm_true, 1),
        },
        "acoustics": {
            "ping_interval_s": 10.0 if kind == "beacon" else 4.0,
            "multipath_prob": round(outliers, 3),
            "multipath_min_m": 3.0,
            "multipath_max_m": 300.0,
            "drop_prob": round(drops, 3),
            "drop_burst_pings": round(rng.uniform(1.0, 4.0), 2),
            "corrupt_position_prob": round(corrupt / 2, 4),
            "corrupt_gross_prob": round(corrupt / 2, 4),
            "temperature_c": round(rng.uniform(4.0, 25.0), 1),
            "salinity_ppt": round(rng.choice([0.2, 33.0, 35.0]), 1),
        },
        "config": {"navigation": {"speed": {"rpm_per_mps": round(rpm_true * (1 + rpm_err), 1)}}},
    }
    dist = rng.uniform(50.0, 2000.0)
    bearing = math.radians(rng.uniform(0.0, 360.0))
    if kind == "beacon":
        motion = rng.choice(["anchored", "drifting", "motoring"])
        sc["boat"] = {
            "north_m": round(dist * math.cos(bearing), 1),
            "east_m": round(dist * math.sin(bearing), 1),
            "speed_mps": round(rng.uniform(0.2, 1.0), 2) if motion == "motoring" else 0.0,
            "heading_deg": round(rng.uniform(0.0, 360.0), 1),
            "drifts_with_current": motion == "drifting",
        }
    else:
        n = 2 if kind == "lbl-2" else 3
        along = n == 2 and rng.random() < 0.5  # the track runs along the baseline
        tps = []
        for i in range(n):
            b = math.radians(heading) if along else bearing + 2 * math.pi * i / n
            r = dist * (1 if i % 2 == 0 else -1) if along else dist * rng.uniform(0.5, 1.0)
            tps.append(
                {
                    "name": f"t{i + 1}",
                    "north_m": round(r * math.cos(b), 1),
                    "east_m": round(r * math.sin(b), 1),
                    "depth_m": round(rng.uniform(5.0, 30.0), 1),
                }
            )
        sc["acoustics"]["transponders"] = tps
    return Draw(seed, kind, outliers, drops, cur_speed > 0.5 * speed and across > 0.7, sc)


@dataclass(frozen=True, slots=True)
class Result:
    draw: Draw
    default: Score | None
    thesis: Score | None
    error: str = ""  # a replay that failed (an exception in the navigator)

    @property
    def diverged(self) -> bool:
        d, t = self.default, self.thesis
        if d is None or t is None:
            return True
        limit = max(DIVERGED_FINAL_M, 2.0 * t.surfacing_m)
        return d.surfacing_m > limit or d.current_rms_mps > DIVERGED_CURRENT_MPS


def _replay(d: Path, mode: str) -> tuple[list[dict], str]:
    out = d / f"out-{mode}.jsonl"
    cmd = [sys.executable, "-m", "navd.cli", "replay", str(d / "measurements.jsonl")]
    cmd += ["--config", str(mode_config(d, mode)), "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or "Traceback" in r.stderr:
        return [], r.stderr.strip().splitlines()[-1] if r.stderr.strip() else f"exit {r.returncode}"
    return read_jsonl(out), ""


def run_one(seed: int, workdir: str, noise_seed: int | None = None) -> Result:
    """Mission ``seed``; with ``noise_seed``, its conditions with another draw of noise."""
    dr = draw(seed)
    d = Path(workdir) / f"mc-{seed}-{noise_seed}"
    write_mission(simulate(scenario_from_dict(dr.scenario), noise_seed or seed), d)
    truth = read_jsonl(d / "truth.jsonl")
    out_d, err_d = _replay(d, "default")
    out_t, err_t = _replay(d, "thesis")
    return Result(
        dr,
        score(out_d, truth) if out_d else None,
        score(out_t, truth) if out_t else None,
        err_d or err_t,
    )


def _mean(xs: list[float]) -> float:
    xs = [x for x in xs if not math.isnan(x)]
    return statistics.fmean(xs) if xs else math.nan


def _row(name: str, rs: list[Result]) -> str:
    ok = [r for r in rs if r.default is not None and r.thesis is not None]
    d = [r.default for r in ok if r.default is not None]
    t = [r.thesis for r in ok if r.thesis is not None]
    rms_d = _mean([x.rms_m for x in d])
    rms_t = _mean([x.rms_m for x in t])
    rms_dr = _mean([x.dr_rms_m for x in d])
    beats_dr = sum(1 for x in d if x.rms_m <= x.dr_rms_m) / len(d) if d else math.nan
    return (
        f"| {name} | {len(rs)} | {sum(1 for r in rs if r.error)} | "
        f"{sum(1 for r in rs if r.diverged)} | {rms_d:.1f} | {rms_t:.1f} | {rms_dr:.1f} | "
        f"{rms_d / rms_t:.2f} | {beats_dr:.2f} | "
        f"{_mean([x.inside95 for x in d]):.2f} | "  # type: ignore[union-attr]
        f"{_mean([x.current_rms_mps for x in d]):.3f} |"  # type: ignore[union-attr]
    )


def table(results: list[Result], n: int) -> str:
    classes: list[tuple[str, list[Result]]] = [
        ("single moving beacon", [r for r in results if r.draw.kind == "beacon"]),
        ("2-transponder LBL", [r for r in results if r.draw.kind == "lbl-2"]),
        ("3-transponder LBL", [r for r in results if r.draw.kind == "lbl-3"]),
        ("outliers < 15 %", [r for r in results if r.draw.outliers < 0.15]),
        ("outliers 15-35 %", [r for r in results if 0.15 <= r.draw.outliers < 0.35]),
        ("outliers >= 35 %", [r for r in results if r.draw.outliers >= 0.35]),
        ("drops >= 35 %", [r for r in results if r.draw.drops >= 0.35]),
        ("cross-current > half the speed", [r for r in results if r.draw.cross_current]),
        ("**all**", results),
    ]
    lines = [
        f"{n} missions, seeds 1..{n}, each with its own drawn conditions (bench/robustness.py).",
        "RMS over the submerged part, in metres; *in95* = fraction of submerged time the truth",
        "lies inside the 95 % ellipse; *cur* = RMS current error (m/s); *default <= DR* =",
        "fraction of missions where the default mode's RMS is no worse than dead reckoning's.",
        "",
        "| class | missions | exceptions | divergences | default rms | thesis rms | DR rms "
        "| default / thesis | default <= DR | in95 | cur |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [_row(name, rs) for name, rs in classes if rs]
    bad = [r for r in results if r.error or r.diverged]
    if bad:
        lines += ["", "Missions that raised or diverged:", ""]
        for r in bad[:20]:
            d = r.default
            what = r.error or (
                f"final {d.surfacing_m:.0f} m, current error {d.current_rms_mps:.2f} m/s"
                if d
                else "no output"
            )
            lines.append(
                f"- seed {r.draw.seed} ({r.draw.kind}, outliers {r.draw.outliers:.0%}, "
                f"drops {r.draw.drops:.0%}): {what}"
            )
    return "\n".join(lines)


def redraw(seed: int, n: int, workers: int) -> int:
    """Is a flagged mission's verdict its conditions', or its one draw of noise's?"""
    noise = [1000 + k for k in range(n)]
    with (
        tempfile.TemporaryDirectory(prefix="navd-mc-") as tmp,
        ProcessPoolExecutor(workers) as ex,
    ):
        results = list(ex.map(run_one, [seed] * n, [tmp] * n, noise))
    print(f"`python -m bench.robustness --redraw {seed} --missions {n}`: mission {seed}'s")
    print("conditions with other draws of the sensor and acoustic noise.\n")
    print(
        "| noise seed | default RMS | thesis RMS | default final | thesis final | limit |"
        " default in 95 % | flagged |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for k, r in zip(noise, results, strict=True):
        d, t = r.default, r.thesis
        if d is None or t is None:
            print(f"| {k} | failed: {r.error} |")
            continue
        limit = max(DIVERGED_FINAL_M, 2.0 * t.surfacing_m)
        print(
            f"| {k} | {d.rms_m:.0f} | {t.rms_m:.0f} | {d.surfacing_m:.0f} | "
            f"{t.surfacing_m:.0f} | {limit:.0f} | {d.inside95:.2f} | "
            f"{'yes' if r.diverged else 'no'} |"
        )
    return 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=120)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument(
        "--redraw",
        type=int,
        metavar="SEED",
        help="mission SEED's conditions again, with --missions other draws of sensor noise",
    )
    args = p.parse_args()
    if args.redraw is not None:
        return redraw(args.redraw, args.missions, args.workers)
    seeds = list(range(1, args.missions + 1))
    with (
        tempfile.TemporaryDirectory(prefix="navd-mc-") as tmp,
        ProcessPoolExecutor(args.workers) as ex,
    ):
        results = list(ex.map(run_one, seeds, [tmp] * len(seeds)))
    cmd = f"`python -m bench.robustness --missions {args.missions}`"
    report(
        f"{cmd}\n\n{table(results, args.missions)}", args.write, "bench-robustness", "Robustness"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
