"""``make demo`` until the daemon exists: simulate a Claytor Lake mission, replay it, report it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from hil.scenario import load_scenario
from hil.sim_cli import write_mission
from hil.world import simulate


def main() -> int:
    out = Path("out/demo")
    sc = load_scenario("claytor-2")
    print(f"simulating {sc.name}: {sc.description}")
    write_mission(simulate(sc, 1), out)
    navd = [sys.executable, "-m", "navd.cli"]
    subprocess.run(
        [
            *navd,
            "replay",
            str(out / "measurements.jsonl"),
            "--config",
            str(out / "config.yaml"),
            "--out",
            str(out / "nav.jsonl"),
        ],
        check=True,
    )
    subprocess.run(
        [
            *navd,
            "report",
            str(out / "nav.jsonl"),
            "--log",
            str(out / "measurements.jsonl"),
            "--truth",
            str(out / "truth.jsonl"),
            "--out",
            str(out / "report"),
        ],
        check=True,
    )
    print(f"mission report: {out / 'report'}/ (track.png, ranges.png, current_uncertainty.png)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
