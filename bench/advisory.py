"""Does the observability advisory fire where it should, and does following it help?

Each drawn mission is a single anchored beacon and a vehicle run radially away from
it with a cross current: the geometry seeds 000 and 001 warn about.  Its sensor
errors, distances, speeds and current are drawn per mission.  Two versions of each:

* as planned: the radial leg to the end;
* following the advice: the same mission, with the same draw of errors, up to the
  first time the advisory (computed from the first version's outputs, as the daemon
  publishes it) says ``weak_cross_range``; from there the vehicle steers the
  suggested heading for the rest of the leg's time.

Both are navigated by the default filter; the error is scored against the truth.
The advisory's firing is also checked on drawn crossing runs (passing the beacon
abeam), where it should stay quiet.

    python -m bench.advisory --missions 24 [--write BENCHMARKS.md]
"""

from __future__ import annotations

import argparse
import copy
import math
import random
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from bench.common import mode_config, report
from navd.analysis.score import score
from navd.filter.advisory import replayed
from navd.formats.outputs import read_outputs
from navd.formats.truth import TruthSample, read_truth
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.schema import Output, split_outputs

SURFACE_BEFORE_S = 60.0
RUN_BEFORE_ADVICE_S = 120.0  # the plan is followed this long before the advice is taken
RANGE_STD_M = 3.0  # the crew config's range noise


def draw(seed: int, crossing: bool = False) -> dict[str, Any]:
    rng = random.Random(seed)
    heading = rng.uniform(0.0, 360.0)
    back = rng.uniform(50.0, 300.0)  # the boat this far behind the start
    h = math.radians(heading)
    north, east = -back * math.cos(h), -back * math.sin(h)
    if crossing:  # the beacon ahead and abeam: the run passes it
        ahead, abeam = rng.uniform(300.0, 500.0), rng.uniform(80.0, 200.0)
        north = ahead * math.cos(h) - abeam * math.sin(h)
        east = ahead * math.sin(h) + abeam * math.cos(h)
    cross = heading + rng.choice((-90.0, 90.0)) + rng.uniform(-30.0, 30.0)
    return {
        "name": f"advisory-{seed}",
        "start_utc": "2026-06-01T12:00:00Z",
        "surface_altitude_m": 0.0,
        "vehicle": {
            "lat": 41.52,
            "lon": -70.67,
            "speed_mps": round(rng.uniform(1.0, 1.5), 2),
            "depth_m": 2.0,
            "surface_before_s": SURFACE_BEFORE_S,
            "legs": [{"heading_deg": round(heading, 1), "duration_s": rng.uniform(600, 900)}],
        },
        "current": {
            "speed_mps": round(rng.uniform(0.1, 0.4), 2),
            "toward_deg": round(cross % 360.0, 1),
        },
        "sensors": {
            "declination_deg": 0.0,
            "compass_bias_deg": round(rng.uniform(-4.0, 4.0), 2),
            "compass_noise_deg": 1.0,
            "rpm_per_mps": round(910.0 * rng.uniform(0.92, 1.08), 1),
        },
        "boat": {
            "north_m": round(north, 1),
            "east_m": round(east, 1),
            "speed_mps": 0.0,
            "drifts_with_current": False,
            "wander_mps": 0.1,
            "gps_std_m": 4.0,
            "transducer_depth_m": 2.0,
            "swing_m": 1.0,
        },
        "acoustics": {"temperature_c": 12.0, "salinity_ppt": 33.0, "modem_mps": 1500.0},
        "config": {"navigation": {"speed": {"rpm_per_mps": 910.0}}},
    }


def _fly(sc: dict[str, Any], seed: int, d: Path) -> tuple[list[Output], list[TruthSample]]:
    write_mission(simulate(scenario_from_dict(sc), seed), d)
    out = d / "out.jsonl"
    cmd = [sys.executable, "-m", "navd.cli", "replay", str(d / "measurements.jsonl")]
    cmd += ["--config", str(mode_config(d, "default")), "--out", str(out)]
    subprocess.run(cmd, capture_output=True, check=True)
    return read_outputs(out), read_truth(d / "truth.jsonl")


def _fire(outputs: list[Output]) -> tuple[float, float] | None:
    """When the advisory first said weak_cross_range while submerged, at least
    ``RUN_BEFORE_ADVICE_S`` into the run (before that, the ranges taken at the surface
    from one spot are weak whatever the plan), and the heading it suggested."""
    est, dec = split_outputs(outputs)
    submerged = {round(e.t, 3) for e in est if e.mode == "submerged"}
    for a in replayed(est, dec, RANGE_STD_M):
        if (
            a.verdict == "weak_cross_range"
            and a.ranges >= 3
            and round(a.t, 3) in submerged
            and a.t >= SURFACE_BEFORE_S + RUN_BEFORE_ADVICE_S
            and a.suggest_heading_deg is not None
        ):
            return a.t, a.suggest_heading_deg
    return None


def run_one(seed: int, workdir: str) -> dict[str, Any]:
    base = draw(seed)
    out, truth = _fly(base, seed, Path(workdir) / f"radial-{seed}")
    fired = _fire(out)
    row: dict[str, Any] = {"seed": seed, "fired": fired is not None}
    s0 = score(out, truth)
    row["planned_rms"], row["planned_final"] = s0.rms_m, s0.surfacing_m
    if fired is not None:
        t_fire, heading = fired
        leg = base["vehicle"]["legs"][0]
        first = max(1.0, t_fire - SURFACE_BEFORE_S)
        follow = copy.deepcopy(base)
        follow["vehicle"]["legs"] = [
            {"heading_deg": leg["heading_deg"], "duration_s": first},
            {"heading_deg": heading, "duration_s": max(1.0, leg["duration_s"] - first)},
        ]
        out1, truth1 = _fly(follow, seed, Path(workdir) / f"follow-{seed}")
        s1 = score(out1, truth1)
        row["t_fire"] = t_fire
        row["followed_rms"], row["followed_final"] = s1.rms_m, s1.surfacing_m
    crossing, truth_c = _fly(draw(seed, crossing=True), seed, Path(workdir) / f"cross-{seed}")
    est_c, dec_c = split_outputs(crossing)
    sub_c = {round(e.t, 3) for e in est_c if e.mode == "submerged"}
    adv_c = [a for a in replayed(est_c, dec_c, RANGE_STD_M) if round(a.t, 3) in sub_c]
    near = [(d.range_m, d.t) for d in dec_c if d.accepted and d.range_m is not None]
    t_abeam = min(near)[1] if near else math.inf
    # the three minutes after passing abeam, when the bearings have swept round
    late = [a for a in adv_c if t_abeam + 60.0 <= a.t <= t_abeam + 180.0]
    row["crossing_weak_share"] = (
        sum(1 for a in late if a.verdict == "weak_cross_range") / len(late) if late else math.nan
    )
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=24)
    p.add_argument("--write", help="put the result into this BENCHMARKS.md")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as work, ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(run_one, range(1, args.missions + 1), [work] * args.missions))
    fired = [r for r in rows if r["fired"]]
    better_rms = sum(1 for r in fired if r["followed_rms"] < r["planned_rms"])
    better_final = sum(1 for r in fired if r["followed_final"] < r["planned_final"])
    mean = statistics.fmean
    cross = [r["crossing_weak_share"] for r in rows if not math.isnan(r["crossing_weak_share"])]
    lines = [
        f"`python -m bench.advisory --missions {args.missions}`: {args.missions} drawn radial "
        "missions (single anchored beacon 50-300 m behind the start, cross current 0.1-0.4 m/s, "
        "compass bias within 4 deg, RPM map within 8 %, 10-15 minute legs), each flown as "
        "planned and again following the first advice; and as many drawn crossing runs.",
        "",
        "| | value |",
        "|---|---|",
        f"| radial missions where the advisory fired (submerged) | {len(fired)} / {len(rows)} |",
        f"| median time from the dive to the advice taken (at least {RUN_BEFORE_ADVICE_S:.0f} s) | "
        f"{statistics.median([r['t_fire'] - SURFACE_BEFORE_S for r in fired]):.0f} s |"
        if fired
        else "| median time to the advice | - |",
        f"| mean RMS error, as planned -> following the advice | "
        f"{mean([r['planned_rms'] for r in fired]):.1f} m -> "
        f"{mean([r['followed_rms'] for r in fired]):.1f} m |"
        if fired
        else "| mean RMS | - |",
        f"| mean error at surfacing, as planned -> following | "
        f"{mean([r['planned_final'] for r in fired]):.1f} m -> "
        f"{mean([r['followed_final'] for r in fired]):.1f} m |"
        if fired
        else "| error at surfacing | - |",
        f"| missions better following the advice (RMS, at surfacing) | "
        f"{better_rms} / {len(fired)}, {better_final} / {len(fired)} |",
        f"| crossing runs: share of the advice 1-3 minutes past abeam that says weak | "
        f"{mean(cross):.2f} |"
        if cross
        else "| crossing runs | - |",
    ]
    report("\n".join(lines), args.write, "bench-advisory", "Observability advisory")
    return 0


if __name__ == "__main__":
    sys.exit(main())
