"""``make bench-soak``: the daemon for an hour on the emulated vehicle, under a fault schedule.

``navd-hil`` runs the one-hour survey and ``navd run`` navigates it, exactly as
``make demo`` does, while every device is unplugged and replugged, stalled for 30 s,
fed bursts of garbage and bad checksums and made to flood at ten times its rate;
the modem answers ``ERROR`` and then nothing; the log disk is full for two
minutes; and a zenoh peer spams commands.  The daemon runs in its own mount
namespace with its log directory on a small tmpfs, so the bench can fill that
disk (through ``/proc/<pid>/root``) without touching the machine's.

Reported, from the daemon's own log and its health messages:
estimates per second per minute (outside the fault windows and overall), ranges
fused against ranges received, RSS and open file descriptors at the start and the
end, exceptions on the daemon's stderr, for each fault the time until health said
so and until it recovered, and the whole log replayed against its live estimates.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from bench.common import report
from navd.formats import jsonlines
from navd.hil.bench_vehicle import BIN, free_port, replay_against_live

SCENARIO = "survey-1h"
DEVICES = ("ahrs", "gps", "pressure", "motor", "modem")
# what health says when a fault of that device shows (the words of its degraded reasons)
SAYS = {
    "ahrs": ("ahrs", "heading"),
    "gps": ("gps",),
    "pressure": ("pressure", "depth"),
    "motor": ("motor", "rpm"),
    "modem": ("modem", "range"),
    "log": ("log",),
}


@dataclass(frozen=True, slots=True)
class Fault:
    name: str
    device: str
    start: float  # mission seconds
    end: float
    on: list[dict]
    off: list[dict]


def schedule(first: float, spacing: float) -> list[Fault]:
    """Every fault once, one at a time, ``spacing`` seconds apart from ``first``."""
    faults: list[Fault] = []
    t = first

    def add(name: str, device: str, length: float, on: list[dict], off: list[dict]) -> None:
        nonlocal t
        faults.append(Fault(name, device, t, t + length, on, off))
        t += length + spacing

    for dev in DEVICES:
        add(f"{dev} unplugged 20 s", dev, 20, [_f(dev, "disconnect")], [_f(dev, "reconnect")])
        add(f"{dev} stalled 30 s", dev, 30, [_f(dev, "stall")], [_f(dev, "unstall")])
        add(f"{dev} garbage 20 s", dev, 20, [_f(dev, "garbage", 0.5)], [_f(dev, "garbage", 0.0)])
        add(
            f"{dev} bad checksums 20 s",
            dev,
            20,
            [_f(dev, "bad_checksum", 0.5)],
            [_f(dev, "bad_checksum", 0.0)],
        )
        add(f"{dev} flood x10 30 s", dev, 30, [_f(dev, "flood", 10)], [_f(dev, "flood", 1)])
    add(
        "modem ERROR 60 s",
        "modem",
        60,
        [_f("modem", "error_reply", 1.0)],
        [_f("modem", "error_reply", 0.0)],
    )
    add(
        "modem silent 60 s",
        "modem",
        60,
        [_f("modem", "drop_reply", 1.0)],
        [_f("modem", "drop_reply", 0.0)],
    )
    # the modem falls online (a CONNECT) and must be escaped back; the pressure sensor
    # loses power and answers "not initialised" until F48
    add("modem online (CONNECT)", "modem", 30, [_f("modem", "online")], [])
    add("pressure power blip", "pressure", 10, [_f("pressure", "power_blip")], [])
    add("log disk full 120 s", "log", 120, [], [])
    add("command spam 10 s", "zenoh", 10, [], [])
    return faults


def _f(device: str, action: str, value: float | int | None = None) -> dict:
    d: dict = {"device": device, "action": action}
    if value is not None:
        d["value"] = value
    return d


def _rss_fds(pid: int) -> tuple[float, int]:
    rss = 0.0
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1]) / 1024.0
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


def _spam(port: int, seconds: float) -> dict[str, int]:
    """A peer sending 100 commands a second: resets and beacons with long names."""
    import zenoh

    c = zenoh.Config()
    c.insert_json5("mode", '"client"')
    c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    c.insert_json5("scouting/multicast/enabled", "false")
    s = zenoh.open(c)
    out = {"sent": 0, "ok": 0, "refused": 0, "unanswered": 0}
    end = time.monotonic() + seconds
    k = 0
    while time.monotonic() < end:
        k += 1
        key, payload = (
            ("cmd/reset", b"{}")
            if k % 2
            else (
                "cmd/beacon",
                jsonlines.dumps({"name": "b" * 100 + str(k), "lat": 1, "lon": 1}),
            )
        )
        replies = [r for r in s.get(f"auv/sim690s/nav/{key}", payload=payload, timeout=1.0) if r.ok]
        out["sent"] += 1
        if not replies:
            out["unanswered"] += 1
        elif (ans := replies[0].ok) is not None and jsonlines.loads(ans.payload.to_bytes())["ok"]:
            out["ok"] += 1
        else:
            out["refused"] += 1
        time.sleep(0.01)
    s.close()
    return out


def run(minutes: float, work: Path, spacing: float = 40.0) -> str:
    d = work / "vehicle"
    d.mkdir(parents=True)
    faults = schedule(first=240.0, spacing=spacing)
    scaled = [f for f in faults if f.end < minutes * 60 - 60]
    plan = []
    for f in scaled:
        plan += [{"t": f.start, **a} for a in f.on] + [{"t": f.end, **a} for a in f.off]
    (work / "faults.yaml").write_bytes(jsonlines.dumps(plan))
    zport = free_port()
    hil_err = (work / "navd-hil.stderr").open("w")
    hil = subprocess.Popen(
        [
            str(BIN / "navd-hil"),
            SCENARIO,
            "--dir",
            str(d),
            "--zenoh-port",
            str(zport),
            "--faults",
            str(work / "faults.yaml"),
        ],
        stderr=hil_err,
    )
    deadline = time.monotonic() + 120
    while not (d / "clock.json").exists():
        if hil.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError((work / "navd-hil.stderr").read_text())
        time.sleep(0.2)
    time.sleep(1.0)  # the ports are served once the banner is out; give it that moment
    t0 = jsonlines.loads((d / "clock.json").read_bytes())["t0_monotonic"]
    logdir = d / "log"
    logdir.mkdir()
    stderr = (work / "navd.stderr").open("w")
    # the daemon's own mount namespace, its log on a tmpfs the bench can fill
    navd = subprocess.Popen(
        [
            "unshare",
            "-m",
            "sh",
            "-c",
            f"mount -t tmpfs -o size=512m tmpfs '{logdir}' && "
            f"exec '{BIN / 'navd'}' run --config '{d / 'navd.yaml'}'",
        ],
        stderr=stderr,
    )
    root = Path(f"/proc/{navd.pid}/root")
    spam: dict[str, int] = {}
    samples: dict[str, tuple[float, int]] = {}
    try:
        time.sleep(60)
        samples["start"] = _rss_fds(navd.pid)
        for f in scaled:
            if f.device == "log":
                _sleep_until(t0 + f.start)
                filler = root / str(logdir).lstrip("/") / "filler"
                subprocess.run(
                    ["dd", "if=/dev/zero", f"of={filler}", "bs=1M", "count=600"],
                    capture_output=True,
                )
                _sleep_until(t0 + f.end)
                filler.unlink()
            elif f.device == "zenoh":
                _sleep_until(t0 + f.start)
                spam = _spam(zport, f.end - f.start)
        _sleep_until(t0 + minutes * 60)
        samples["end"] = _rss_fds(navd.pid)
        # what only this process saw, kept so that --summarise can report a kept run again
        (work / "samples.json").write_bytes(
            jsonlines.dumps({"samples": samples, "spam": spam, "t0": t0, "spacing": spacing})
        )
        copy = work / "log"
        shutil.copytree(root / str(logdir).lstrip("/"), copy)
    finally:
        navd.send_signal(signal.SIGTERM)
        navd.wait(timeout=30)
        hil.send_signal(signal.SIGTERM)
        hil.wait(timeout=30)
        stderr.close()
        hil_err.close()
    return summarise(work, d, copy, scaled, t0, samples, spam, minutes)


def _sleep_until(t: float) -> None:
    time.sleep(max(0.0, t - time.monotonic()))


def summarise(work, d, copy, faults, t0, samples, spam, minutes) -> str:  # noqa: ANN001
    files = sorted(copy.glob("navd-*.jsonl"))
    lines, cut = [], 0
    for f in files:
        for x in f.read_text().splitlines():
            try:
                lines.append(jsonlines.loads(x))
            except jsonlines.DecodeError:
                cut += 1  # the line being written when the disk filled up, cut short
    est = [o["t"] - t0 for o in lines if o.get("type") == "estimate"]
    health = [o for o in lines if o.get("type") == "health"]
    windows = [(f.start, f.end + 15.0) for f in faults]
    per_min: list[tuple[int, float, bool]] = []
    for m in range(1, int(minutes) - 1):
        n = sum(1 for t in est if 60 * m <= t < 60 * (m + 1))
        inside = any(a < 60 * (m + 1) and b > 60 * m for a, b in windows)
        per_min.append((m, n / 60.0, inside))
    outside = [r for _, r, inside in per_min if not inside]
    last = health[-1] if health else {}
    pings = last.get("pings", {})
    exceptions = (work / "navd.stderr").read_text().count("Traceback")
    rows = []
    for f in faults:
        words = SAYS.get(f.device, ())
        said = [h for h in health if f.start <= h["t"] - t0 and _says(h, words)]
        t_said = said[0]["t_mono"] - t0 - f.start if said else None
        after = [h for h in health if h["t"] - t0 >= f.end]
        t_ok = next((h["t"] - t0 - f.end for h in after if not _says(h, words)), None)
        late = t_said is None or t_said > f.end - f.start + 5
        said_s = "not said" if late else f"{t_said:.0f} s"
        ok_s = "-" if t_ok is None else f"{t_ok:.0f} s"
        rows.append(f"| {f.name} | {f.start:.0f} | {said_s} | {ok_s} |")
    check = replay_against_live(files, d / "navd.yaml", work / "replay.jsonl")
    rss0, fd0 = samples.get("start", (math.nan, 0))
    rss1, fd1 = samples.get("end", (math.nan, 0))
    out = [
        f"{minutes:.0f} minutes of `{SCENARIO}` on the emulated vehicle, {len(faults)} faults one "
        "after another (bench/soak.py).",
        "",
        f"- estimates per second, per minute outside the fault windows: min "
        f"{min(outside):.2f}, median {statistics.median(outside):.2f} (target >= 9.5); "
        f"inside them: min {min((r for _, r, i in per_min if i), default=math.nan):.2f}",
        f"- ranges received {pings.get('ranges', 0)}, fused {pings.get('fused', 0)}; pings sent "
        f"{pings.get('sent', 0)}, no reply {pings.get('no_reply', 0)}, timeouts "
        f"{pings.get('timeouts', 0)}, refused {pings.get('refused', 0)}, modem escapes "
        f"{last.get('modem', {}).get('escapes', 0)}",
        f"- log lines that do not parse (cut when the disk filled): {cut}",
        f"- RSS {rss0:.1f} MB after the first minute, {rss1:.1f} MB at the end "
        f"(growth {rss1 - rss0:+.1f} MB, target < 10); open files {fd0} and {fd1}",
        f"- exceptions on the daemon's stderr: {exceptions}",
        f"- command spam: {spam}",
        f"- the whole log replayed: {check.common} of {check.live} estimates at the same times, "
        f"largest difference from the live ones {check.worst:.1e}",
        "",
        "| fault | at (s) | health said it after | health ok again after the fault |",
        "|---|---|---|---|",
        *rows,
    ]
    return "\n".join(out)


def summarise_kept(work: Path, minutes: float, spacing: float) -> str:
    """The report of a run kept with ``--keep``, from its files.  What only the bench
    process saw (RSS, open files, the spam's answers) comes from ``samples.json``,
    which runs before that file existed lack."""
    kept = work / "samples.json"
    extra = jsonlines.loads(kept.read_bytes()) if kept.exists() else {}
    faults = schedule(first=240.0, spacing=extra.get("spacing", spacing))
    scaled = [f for f in faults if f.end < minutes * 60 - 60]
    clock = jsonlines.loads((work / "vehicle" / "clock.json").read_bytes())
    t0 = extra.get("t0", clock["t0_monotonic"])
    samples = {k: tuple(v) for k, v in extra.get("samples", {}).items()}
    return summarise(
        work, work / "vehicle", work / "log", scaled, t0, samples, extra.get("spam", {}), minutes
    )


def _says(h: dict, words: tuple[str, ...]) -> bool:
    return any(any(w in p for w in words) for p in h.get("degraded", []))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--minutes", type=float, default=60.0)
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument("--keep", help="keep the run's files (log, configs, stderr) in this directory")
    p.add_argument("--spacing", type=float, default=40.0, help="seconds between faults")
    p.add_argument("--summarise", help="report a run kept with --keep in this directory again")
    args = p.parse_args()
    if args.summarise:
        body = summarise_kept(Path(args.summarise), args.minutes, args.spacing)
    elif args.keep:
        body = run(args.minutes, Path(args.keep), args.spacing)
    else:
        with tempfile.TemporaryDirectory(prefix="navd-soak-") as tmp:
            body = run(args.minutes, Path(tmp), args.spacing)
    report(
        f"`python -m bench.soak --minutes {args.minutes:g}`\n\n{body}",
        args.write,
        "bench-soak",
        "Soak",
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
