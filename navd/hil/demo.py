"""``make demo``: the unchanged daemon on the emulated vehicle, watched live, then reported.

Starts ``navd-hil demo`` (five device emulators on pseudo-terminals, moved along a
two-minute Claytor-Lake-like mission by the world simulator), ``navd run`` against
those ports exactly as on the vehicle, and ``navd watch`` to show the live estimate
over zenoh on loopback.  At the end it replays the daemon's log and writes the
mission report.  No hardware, no router, no internet.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from navd.formats import jsonlines
from navd.hil.bench_vehicle import BIN, BenchVehicle


def main() -> int:
    out = Path("out/demo")
    shutil.rmtree(out, ignore_errors=True)
    veh = out / "vehicle"
    out.mkdir(parents=True)
    navd_err = (out / "navd.stderr").open("w")
    v = BenchVehicle(veh, navd_stderr=navd_err)
    print(v.banner)
    print(f"navd run --config {v.config} (pid {v.navd.pid}); live estimate over zenoh:")
    try:
        subprocess.run(
            [
                str(BIN / "navd"),
                "watch",
                "--config",
                str(v.config),
                "--seconds",
                "128",
                "--every",
                "2",
            ],
            check=False,
        )
    except KeyboardInterrupt:
        pass
    finally:
        v.stop()
        navd_err.close()
    logfile = v.logfile()
    t0 = v.t0_monotonic
    with (veh / "truth.jsonl").open() as src, (out / "truth_monotonic.jsonl").open("w") as dst:
        for line in src:
            s = jsonlines.loads(line)
            s["t"] = round(s["t"] + t0, 9)
            dst.write(jsonlines.dumps_line(s))
    navd_cmd = [str(BIN / "navd")]
    subprocess.run(
        [
            *navd_cmd,
            "replay",
            str(logfile),
            "--config",
            str(v.config),
            "--out",
            str(out / "nav.jsonl"),
        ],
        check=True,
    )
    subprocess.run(
        [
            *navd_cmd,
            "report",
            str(out / "nav.jsonl"),
            "--log",
            str(logfile),
            "--truth",
            str(out / "truth_monotonic.jsonl"),
            "--out",
            str(out / "report"),
        ],
        check=True,
    )
    print(f"\ndaemon log: {logfile}\nmission report: {out / 'report'}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
