"""``make bench-replay``: how fast ``navd replay`` runs, against what plain numpy does, and
how its memory grows with the mission.

Simulates the ``survey-1h`` scenario (3,700 s, 10 Hz sensors, a ping every 10 s),
then times the ``navd replay`` command end to end (process start, reading and
parsing the log, filtering, writing the output), best of ``--runs``, beside the
plain-numpy floor of ``bench/numpy_floor.py`` on the same log in the same run.
Then the same survey flown for 10 minutes to 24 hours (boxes of the same lines),
and the peak RSS of ``navd replay`` on each, without and with ``--smooth``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, cast

from bench.common import mode_config, report
from navd import files
from navd.analysis.score import position_rms, score
from navd.filter import ekf_step, relinearise
from navd.formats import jsonlines
from navd.formats.outputs import read_outputs
from navd.formats.truth import read_truth
from navd.hil.scenario import load_scenario, scenario_dir, scenario_from_dict
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.schema import Estimate, RangeDecision

_LENGTHS_S = (600, 3600, 3 * 3600, 24 * 3600)


def _survey(duration_s: float) -> dict[str, Any]:
    """survey-1h's lines, as boxes (north, east, south, west) that keep near the boat."""
    # a bundled scenario: a mapping, as its own tests check
    data = cast(dict[str, Any], files.load_yaml(scenario_dir() / "survey-1h.yaml"))
    box = [(0, 270), (90, 30), (180, 270), (270, 30)]
    legs, t, k = [], 0.0, 0
    while t < duration_s:
        heading, d = box[k % 4]
        legs.append({"heading_deg": heading, "duration_s": min(d, duration_s - t)})
        t += d
        k += 1
    data["vehicle"]["legs"] = legs
    data["name"] = f"survey-{duration_s:g}s"
    return data


# The child reports its own high-water mark: rusage's maxrss would carry this process's
# size over fork and exec, /proc's VmHWM is the new program's alone.
_HWM = (
    "import runpy, sys\n"
    "sys.argv = sys.argv[1:]\n"
    "try:\n"
    "    runpy.run_path(sys.argv[0], run_name='__main__') if sys.argv[0].endswith('.py') "
    "else runpy.run_module(sys.argv[0], run_name='__main__', alter_sys=True)\n"
    "finally:\n"
    "    hwm = [x for x in open('/proc/self/status') if x.startswith('VmHWM')][0]\n"
    "    sys.stderr.write('HWM ' + hwm.split()[1] + '\\n')\n"
)


def _run(cmd: list[str], pure: bool = False) -> tuple[float, float]:
    """Wall time (s) and peak RSS (MB) of ``python -m MODULE ARGS`` or ``python FILE ARGS``
    (``pure``: with navd's compiled parts kept out, navd/filter/ekf_step.py and
    navd/filter/relinearise.py)."""
    target = cmd[2:] if cmd[1] == "-m" else cmd[1:]
    env = {**os.environ, "NAVD_PURE_PYTHON": "1"} if pure else None
    t0 = time.perf_counter()
    r = subprocess.run([cmd[0], "-c", _HWM, *target], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    hwm = [ln for ln in r.stderr.splitlines() if ln.startswith("HWM ")]
    if r.returncode not in (0, None) or not hwm:
        raise SystemExit(f"bench-replay: {' '.join(cmd)} failed: {r.stderr[-300:]}")
    return wall, int(hwm[-1].split()[1]) / 1024.0


def _replay_cmd(d: Path, mode: str, smooth: bool) -> list[str]:
    cmd = [sys.executable, "-m", "navd.cli", "replay", str(d / "measurements.jsonl")]
    cmd += ["--config", str(mode_config(d, mode)), "--out", str(d / "out.jsonl")]
    return cmd + (["--smooth"] if smooth else [])


def speed(d: Path, runs: int, sim_s: float) -> list[str]:
    truth = read_truth(d / "truth.jsonl")
    n_lines = sum(1 for _ in (d / "measurements.jsonl").open()) - 1
    floor_cmd = [sys.executable, str(Path(__file__).with_name("numpy_floor.py"))]
    floor_cmd += [str(d / "measurements.jsonl"), str(d / "floor.jsonl")]
    floor = min(_run(floor_cmd)[0] for _ in range(runs))
    read_cmd = [sys.executable, "-m", "bench.log_read", str(d / "measurements.jsonl")]
    read = min(_run(read_cmd)[0] for _ in range(runs))
    floor_rms = position_rms(
        ((o["t"], o["lat"], o["lon"]) for o in jsonlines.read(d / "floor.jsonl")), truth
    )
    rows = []
    ticks = 0
    runs_of = (("default", False, False), ("default", False, True), ("thesis", False, False),
               ("default", True, False))
    for mode, smooth, pure in runs_of:
        if pure and not (ekf_step.COMPILED or relinearise.COMPILED):
            continue  # the row above took the reference step already
        best = min(_run(_replay_cmd(d, mode, smooth), pure)[0] for _ in range(runs))
        out = read_outputs(d / "out.jsonl")
        steps = sum(1 for o in out if isinstance(o, Estimate))
        ranges = sum(1 for o in out if isinstance(o, RangeDecision))
        ticks = ticks or steps
        label = mode + (" + RTS smoother" if smooth else "") + (
            ", Python step and solve (`NAVD_PURE_PYTHON=1`)" if pure else "")
        rows.append(
            f"| {label} | {n_lines} | {steps} | {ranges} | {best:.2f} | "
            f"{out[-1].t / best:,.0f} | {1e6 * best / steps:.0f} | {best / floor:.1f} "
            f"| {score(out, truth).rms_m:.1f} |"
        )
    return [
        f"One-hour mission (`survey-1h`, seed 1), best of {runs} runs of the whole "
        "`navd replay` command, beside the plain-numpy floor (`bench/numpy_floor.py`: "
        "orjson, an 8-state EKF over the same steps and updates, the same number of "
        f"lines written) in the same run: **{floor:.2f} s**, RMS {floor_rms:.1f} m against "
        "the truth (a floor that navigates, not a rival). Simulating the mission took "
        f"{sim_s:.2f} s. The default mode's prediction step and window solve are "
        + ("compiled (navd/filter/_ekf_step.c, navd/filter/_window.c)"
           if ekf_step.COMPILED and relinearise.COMPILED else
           "Python's (no C compiler when navd was installed)")
        + ", but where the row says otherwise.",
        "",
        "| mode | log records | filter steps out | ranges | wall time (s) | x real time "
        "| us per step | / numpy floor | RMS (m) |",
        "|---|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        "Targets (issue 24): 5,000 x real time (0.72 s) and within 1.3 x the floor "
        f"({1.3 * floor:.2f} s here). navd's start-up and log reader alone "
        "(`python -m bench.log_read LOG`: every record read and checked as replay does, "
        f"nothing navigated or written), best of {runs}: **{read:.2f} s**, "
        f"{read / floor:.2f} x the floor, which leaves {max(0.0, 1.3 * floor - read):.2f} s "
        f"({1e6 * max(0.0, 1.3 * floor - read) / max(1, ticks):.1f} us a tick) for "
        "each tick's two filter steps, its estimate and its line of output.",
    ]


def _span(seconds: float) -> str:
    return f"{seconds / 60:g} min" if seconds < 3600 else f"{seconds / 3600:g} h"


def memory(tmp: Path, lengths: list[float]) -> list[str]:
    rows = []
    for length in lengths:
        d = tmp / f"len-{length:g}"
        write_mission(simulate(scenario_from_dict(_survey(length)), 1), d)
        size = (d / "measurements.jsonl").stat().st_size / 1e6
        plain = _run(_replay_cmd(d, "default", False))
        smooth = _run(_replay_cmd(d, "default", True))
        rows.append(
            f"| {_span(length)} | {size:.0f} | {plain[1]:.0f} | {plain[0]:.1f} | "
            f"{smooth[1]:.0f} | {smooth[0]:.1f} |"
        )
        for p in d.iterdir():
            p.unlink()
    return [
        "Peak RSS of `navd replay` (default mode) against mission length: survey-1h's "
        "lines flown as boxes for as long, seed 1.",
        "",
        "| mission | log (MB) | peak RSS (MB) | wall (s) | with --smooth: peak RSS (MB) "
        "| wall (s) |",
        "|---|---|---|---|---|---|",
        *rows,
    ]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument(
        "--lengths", type=float, nargs="*", default=list(_LENGTHS_S),
        help="mission lengths (s) for the memory table; none to leave it out",
    )
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "survey-1h"
        t0 = time.perf_counter()
        mission = simulate(load_scenario("survey-1h"), 1)
        sim_s = time.perf_counter() - t0
        write_mission(mission, d)
        lines = speed(d, args.runs, sim_s)
        if args.lengths:
            lines += ["", *memory(Path(tmp), args.lengths)]
    cmd = "`python -m bench.replay_speed" + (
        f" --lengths {' '.join(f'{x:g}' for x in args.lengths)}`" if args.lengths else "`"
    )
    report("\n".join([cmd, "", *lines]), args.write, "bench-replay", "Replay speed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
