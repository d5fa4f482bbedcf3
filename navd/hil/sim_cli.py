"""``navd-sim SCENARIO --seed N --out DIR``: a simulated mission as navd would have logged it.

Writes ``measurements.jsonl`` (measurement log v1), ``config.yaml`` (what the crew
would have configured) and ``truth.jsonl`` (the vehicle's true track at the sensor
rate), plus ``mission.json`` with the ping statistics.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping
from pathlib import Path

import yaml

from navd.formats import jsonlines
from navd.formats.mlog import MeasurementWriter
from navd.formats.truth import write_truth
from navd.hil.scenario import Scenario, list_scenarios, load_scenario
from navd.hil.world import Mission, simulate
from navd.settings import ConfigError, config_from_dict, deep_merge


def crew_config(sc: Scenario) -> dict[str, object]:
    """The navd config a crew would write for this mission: site facts, not the truth's errors."""
    a = sc.acoustics
    auto = {
        "navigation": {
            "magnetic_declination_deg": sc.sensors.declination_deg,
            "speed": {"rpm_per_mps": sc.sensors.rpm_per_mps},
            "sound_speed": {
                "model": "coppens",
                "temperature_c": a.temperature_c,
                "salinity_ppt": a.salinity_ppt,
                "modem_mps": a.modem_mps,
            },
        },
        "beacons": {
            "udb": {
                "depth": sc.boat.transducer_depth_m,
                "turnaround_s": a.turnaround_s,
                # what the crew knows of the beacon's GPS (a receiver's data-sheet figure)
                "position_std_m": sc.boat.gps_std_m,
            }
        },
        "site": {"name": sc.name},
    }
    merged = deep_merge(auto, sc.config)
    config_from_dict(merged)  # a scenario must produce a valid config
    return merged


def mission_config(m: Mission) -> dict[str, object]:
    """The crew's config of a simulated mission: :func:`crew_config` with what the
    simulator adds (a fixed array's surveyed transponders)."""
    return deep_merge(crew_config(m.scenario), m.config_overrides)


def write_mission(
    m: Mission, out_dir: Path, config_overrides: Mapping[str, object] | None = None
) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    with (out_dir / "measurements.jsonl").open("w", encoding="utf-8") as fh:
        w = MeasurementWriter(fh, m.scenario.start_utc, scenario=m.scenario.name, seed=m.seed)
        for rec in m.records:
            w.write(rec)
    cfg = deep_merge(mission_config(m), config_overrides or {})
    (out_dir / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False), encoding="utf-8")
    with (out_dir / "truth.jsonl").open("w", encoding="utf-8") as fh:
        write_truth(fh, m.truth)
    meta = {"scenario": m.scenario.name, "seed": m.seed, "pings": m.pings, "replies": m.replies}
    (out_dir / "mission.json").write_text(jsonlines.dumps_line(meta), encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="navd-sim",
        description="A simulated mission as navd would have logged it: measurements.jsonl "
        "(navd replay's input), truth.jsonl, config.yaml and mission.json in --out.",
    )
    p.add_argument("scenario", nargs="?", help="scenario name or YAML path (--list to see them)")
    p.add_argument("--seed", type=int, default=1, help="random seed of the sensor errors")
    p.add_argument("--out", help="output directory (required unless --list)")
    p.add_argument("--list", action="store_true", help="list the bundled scenarios")
    args = p.parse_args(argv)
    if args.list or not args.scenario:
        print("\n".join(list_scenarios()))
        return 0
    if not args.out:
        p.error("--out is required")
    try:
        sc = load_scenario(args.scenario)
        mission = simulate(sc, args.seed)
        write_mission(mission, Path(args.out))
    except ConfigError as exc:
        print(f"navd-sim: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"navd-sim: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(
        f"navd-sim: {sc.name} seed {args.seed}: {len(mission.records)} records, "
        f"{mission.replies}/{mission.pings} pings answered -> {args.out}",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
