"""``make bench-daemon``: the daemon against the emulators for ten minutes.

Runs ``navd-hil demo`` and ``navd run`` as on the bench, then reads the daemon's
CPU time, its main thread's wake-ups (voluntary context switches) and peak RSS from
/proc, and its own health (tick lateness over the last
6,000 ticks, the time from a tick's deadline to the estimate handed to zenoh).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import report
from navd.formats import jsonlines
from navd.hil.bench_vehicle import BenchVehicle


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _threads_cpu_s(pid: int) -> tuple[float, float]:
    """CPU seconds of the main thread (Python: the event loop, decoders, filter) and of
    every other thread (zenoh's runtime and the I/O threads beside it)."""
    main = other = 0.0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            f = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # a thread that ended
        cpu = (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
        if int(task.name) == pid:
            main += cpu
        else:
            other += cpu
    return main, other


def _wakeups(pid: int) -> int:
    """How many times the main thread (the event loop) has gone to sleep and woken."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("voluntary_ctxt_switches:"):
            return int(line.split()[1])
    return 0


def _profile_rows(path: Path, n: int = 12) -> list[str]:
    import pstats

    st = pstats.Stats(str(path))
    rows = sorted(st.stats.items(), key=lambda kv: -kv[1][2])  # type: ignore[attr-defined]
    total = sum(v[2] for k, v in rows if "poll" not in k[2])
    out = [
        f"Where the Python thread's time goes (cProfile, `--profile`; waiting in epoll left "
        f"out; {total:.1f} s profiled, cProfile's own cost included):",
        "",
        "| function | calls | own time (s) | share |",
        "|---|---|---|---|",
    ]
    for (file, line, fn), v in rows:
        if "poll" in fn:
            continue
        where = f"{Path(file).name}:{line} {fn}" if line else fn
        out.append(f"| `{where}` | {v[1]} | {v[2]:.2f} | {v[2] / total:.0%} |")
        if len(out) >= n + 4:
            break
    return out


def _hwm_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument("--profile", action="store_true", help="run the daemon under cProfile too")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp) / "vehicle"
        prof = Path(tmp) / "navd.prof" if args.profile else None
        v = BenchVehicle(d, navd_stderr=subprocess.DEVNULL, profile=prof)
        navd = v.navd
        time.sleep(5.0)
        cpu0, t0 = _cpu_s(navd.pid), time.monotonic()
        main0, other0 = _threads_cpu_s(navd.pid)
        woke0 = _wakeups(navd.pid)
        time.sleep(args.seconds)
        span = time.monotonic() - t0
        cpu = (_cpu_s(navd.pid) - cpu0) / span * 100.0
        main1, other1 = _threads_cpu_s(navd.pid)
        woke = (_wakeups(navd.pid) - woke0) / span
        cpu_main, cpu_other = (main1 - main0) / span * 100, (other1 - other0) / span * 100
        hwm = _hwm_mb(navd.pid)
        v.stop()
        logfile = v.logfile()
        health = None
        with logfile.open() as fh:
            for line in fh:
                if '"type":"health"' in line:
                    health = line
        if health is None:
            raise SystemExit("bench-daemon: the daemon logged no health")
        h = jsonlines.loads(health)
        profile = _profile_rows(prof) if prof is not None and prof.exists() else []
    tl, pl = h["tick_lateness_ms"], h["publish_latency_ms"]
    body = "\n".join(
        [
            f"`navd run` against `navd-hil demo` (all five emulators on ptys, zenoh on loopback) "
            f"for {args.seconds:.0f} s; AHRS streaming at 20 Hz, pressure and RPM polled at 10 Hz.",
            "",
            "| measure | value | target |",
            "|---|---|---|",
            f"| CPU, % of one core | {cpu:.2f} | < 1.5 |",
            f"| of which the Python thread / zenoh's and other threads | {cpu_main:.2f} / "
            f"{cpu_other:.2f} | |",
            f"| event-loop wake-ups a second | {woke:.0f} | |",
            f"| peak RSS (MB) | {hwm:.0f} | |",
            f"| tick lateness p50 / p99 / max (ms) | {tl['p50']} / {tl['p99']} / {tl['max']} "
            "| p99 < 5 |",
            f"| tick deadline to zenoh put, p50 / p99 (ms) | {pl['p50']} / {pl['p99']} "
            "| p99 < 10 |",
            f"| tick overruns | {h['tick_overruns']} | 0 |",
            "",
            "Latency is measured from the tick's deadline, not from a serial byte: a byte is "
            "fed to the filter the moment it is read, and waits for the next 10 Hz tick "
            "(0 to 100 ms) to appear in a published estimate.",
            *(["", "With `--profile` the daemon runs under cProfile, so its CPU above is "
               "inflated.", "", *profile] if profile else []),
        ]
    )
    cmd = f"`python -m bench.daemon_perf --seconds {args.seconds:g}" + (
        " --profile`" if args.profile else "`"
    )
    report(f"{cmd}\n\n{body}", args.write, "bench-daemon", "Daemon")
    return 0


if __name__ == "__main__":
    sys.exit(main())
