"""``make bench-soak``: the daemon for an hour on the emulated vehicle, under a fault schedule.

``navd-hil`` runs the one-hour survey and ``navd run`` navigates it, exactly as
``make demo`` does, while every device is unplugged and replugged, stalled for 30 s,
fed bursts of garbage and bad checksums and made to flood at ten times its rate;
the modem answers ``ERROR`` and then nothing; the log disk is full for two
minutes; a zenoh peer spams commands; and, for what reaches the autopilot: the GPS
gives one fix at (0, 0) at the surface, navd is killed (``kill -9``) and hung long
enough for the watchdog while submerged and started again as systemd would, a crew
member's session publishes forged estimates, and a flood of malformed commands
runs while an autopilot sends its own.  The daemon runs with the shipped access
control (config/zenoh.json5, users made here) and its checkpoint in a state
directory, in a mount namespace of its own (held by a process of the bench, so
that restarts share it) with its log directory on a small tmpfs, so the bench can
fill that disk (through ``/proc/<pid>/root``) without touching the machine's.

Reported, from the daemon's own log and its health messages:
estimates per second per minute (outside the fault windows and overall), ranges
fused against ranges received, RSS and open file descriptors at the start and the
end, exceptions on the daemon's stderr, for each fault the time until health said
so and until it recovered, and the whole log replayed against its live estimates;
for each fault of what reaches the autopilot, how long estimates stopped and how
many estimates marked ``ok`` in the two minutes after it lay outside their 99 %
ellipse around the truth (against the same share over the whole run), what the
autopilot's client saw of the forgeries, and how its commands were answered.
"""

from __future__ import annotations

import argparse
import contextlib
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
    "navd": ("resumed",),
    "gps-glitch": ("refused in a row",),
}
#: chi-square on two degrees of freedom at 99 %: the 99 % ellipse
CHI2_99 = 9.21
#: how long after a fault its estimates are judged against the truth
JUDGED_S = 60.0
#: the GPS glitch comes while the vehicle is still at the surface (the first minute)
GLITCH_AT = 45.0


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

    # what reaches the autopilot (all submerged: the survey is under from 60 s on)
    add("navd killed (kill -9), restarted 2 s later", "navd", 10, [], [])
    add("navd hung 6 s (the watchdog), restarted 2 s later", "navd", 10, [], [])
    add("forged estimates from a crew session 20 s", "forge", 20, [], [])
    add("malformed command flood 10 s, an autopilot commanding", "flood", 10, [], [])
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
    glitch = Fault(
        "GPS fix at (0, 0) at the surface",
        "gps-glitch",
        GLITCH_AT,
        GLITCH_AT + 1,
        [{"device": "gps", "action": "glitch", "value": 1}],
        [],
    )
    return [glitch, *faults]


def _f(device: str, action: str, value: float | int | None = None) -> dict:
    d: dict = {"device": device, "action": action}
    if value is not None:
        d["value"] = value
    return d


def _sample(samples: dict[str, tuple[float, int]], pid: int) -> None:
    """The first-minute sample of a restarted daemon (unless it was restarted again)."""
    with contextlib.suppress(OSError):  # restarted again meanwhile
        samples["start"] = _rss_fds(pid)


def _rss_fds(pid: int) -> tuple[float, int]:
    rss = 0.0
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1]) / 1024.0
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


def _session(port: int, user: str, password: str):  # noqa: ANN202 - a zenoh.Session
    import zenoh

    c = zenoh.Config()
    c.insert_json5("mode", '"client"')
    c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("transport/auth/usrpwd", json.dumps({"user": user, "password": password}))
    return zenoh.open(c)


def _spam(port: int, seconds: float) -> dict[str, int]:
    """An autopilot's session sending 100 commands a second: resets and beacons with
    long names."""
    s = _session(port, "autopilot", PILOT)
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


def _flood(port: int, seconds: float) -> dict[str, int]:
    """Three threads of malformed commands from one session, and meanwhile an
    autopilot's own session sending one well-formed beacon command a second."""
    import threading

    flooder = _session(port, "autopilot", PILOT)
    stop = threading.Event()
    sent = [0]

    def flood() -> None:
        while not stop.is_set():
            flooder.get("auv/sim690s/nav/cmd/beacon", payload=b'{"name": ', timeout=1.0)
            sent[0] += 1

    threads = [threading.Thread(target=flood, daemon=True) for _ in range(3)]
    for th in threads:
        th.start()
    pilot = _session(port, "autopilot", PILOT)
    out = {"pilot_sent": 0, "pilot_ok": 0, "pilot_refused": 0, "pilot_unanswered": 0}
    end = time.monotonic() + seconds
    k = 0
    while time.monotonic() < end:
        k += 1
        body = jsonlines.dumps({"name": f"spare{k % 4}", "lat": 41.52, "lon": -70.67})
        replies = [r for r in pilot.get("auv/sim690s/nav/cmd/beacon", payload=body, timeout=2.0)]
        out["pilot_sent"] += 1
        ok = [r.ok for r in replies if r.ok is not None]
        if not ok:
            out["pilot_unanswered"] += 1
        elif jsonlines.loads(ok[0].payload.to_bytes())["ok"]:
            out["pilot_ok"] += 1
        else:
            out["pilot_refused"] += 1
        time.sleep(1.0)
    stop.set()
    for th in threads:
        th.join(5)
    out["malformed_sent"] = sent[0]
    pilot.close()
    flooder.close()
    return out


def _forge(port: int, seconds: float) -> dict[str, int]:
    """A crew member's session (an observer's credentials, a listening peer) putting
    forged estimates, health and ranges, and answering ``latest`` in navd's place."""
    import zenoh

    c = zenoh.Config()
    c.insert_json5("mode", '"peer"')
    c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    c.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{free_port()}"]))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("transport/auth/usrpwd", json.dumps({"user": "observer", "password": WATCH}))
    s = zenoh.open(c)
    forged = {
        "t": 1.0,
        "lat": 0.0,
        "lon": 0.0,
        "std_n": 0.1,
        "std_e": 0.1,
        "cov_ne": 0.0,
        "current_n": 0.0,
        "current_e": 0.0,
        "depth": 0.0,
        "mode": "submerged",
        "integrity": "ok",
        "schema": 1,
        "seq": 0,
    }
    q = s.declare_queryable(
        "auv/sim690s/nav/latest", lambda query: query.reply(query.key_expr, json.dumps(forged))
    )
    token = s.liveliness().declare_token("auv/ghost/nav/alive")
    n = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        s.put("auv/sim690s/nav/estimate", json.dumps(forged))
        s.put("auv/sim690s/nav/health", json.dumps({"t": 1.0, "ok": True, "schema": 1}))
        n += 1
        time.sleep(0.1)
    token.undeclare()
    q.undeclare()
    s.close()
    return {"forged_puts": n}


PILOT = "pilot-soak-secret"  # made up for the run: the bench's own users file
WATCH = "watch-soak-secret"


class _Autopilot:
    """What an autopilot's NavClient receives over the whole run: every estimate (a
    forged one has lat 0), each Stale or Gone, and ``latest`` asked during the forgery."""

    def __init__(self, port: int) -> None:
        import zenoh

        from navd.client import NavClient

        c = zenoh.Config()
        c.insert_json5(
            "transport/auth/usrpwd", json.dumps({"user": "autopilot", "password": PILOT})
        )
        self.client = NavClient("sim690s", [f"tcp/127.0.0.1:{port}"], config=c, stale_s=1.0)
        self.estimates = 0
        self.forged = 0
        self.unavailable: list[tuple[float, str]] = []
        self.latest_forged = 0
        self.latest_asked = 0
        self.client.subscribe(self._on_estimate, on_unavailable=self._on_unavailable)

    def _on_estimate(self, e) -> None:  # noqa: ANN001 - a navd.schema.Estimate
        self.estimates += 1
        if abs(e.lat) < 1.0 and abs(e.lon) < 1.0:
            self.forged += 1

    def _on_unavailable(self, why) -> None:  # noqa: ANN001
        self.unavailable.append((time.monotonic(), f"{type(why).__name__}: {why}"))

    def ask_latest(self) -> None:
        e = self.client.latest()
        self.latest_asked += 1
        if e is not None and abs(e.lat) < 1.0:
            self.latest_forged += 1

    def close(self) -> None:
        self.client.close()


def _secure(work: Path) -> Path:
    """The shipped access control with users made for this run, and the daemon's
    state directory: an overlay on navd-hil's navd.yaml."""
    shipped = Path(__file__).resolve().parent.parent / "config" / "zenoh.json5"
    users = work / "zenoh-users.txt"
    users.write_text(f"autopilot:{PILOT}\nobserver:{WATCH}\n")
    zfile = work / "zenoh.json5"
    zfile.write_text(shipped.read_text().replace("/etc/navd/zenoh-users.txt", str(users)))
    (work / "state").mkdir()
    site = work / "soak.yaml"
    site.write_text(f"zenoh: {{config_file: '{zfile}'}}\ncheckpoint: {{dir: '{work / 'state'}'}}\n")
    return site


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
    site = _secure(work)
    logdir = d / "log"
    logdir.mkdir()
    stderr = (work / "navd.stderr").open("w")
    # a mount namespace of the bench's, its log directory on a tmpfs the bench can fill;
    # each daemon (the first, and those systemd would start again) runs inside it
    holder = subprocess.Popen(
        [
            "unshare",
            "-m",
            "sh",
            "-c",
            f"mount -t tmpfs -o size=512m tmpfs '{logdir}' && exec sleep 86400",
        ]
    )
    time.sleep(0.5)
    root = Path(f"/proc/{holder.pid}/root")
    command = [
        "nsenter",
        "-t",
        str(holder.pid),
        "-m",
        "--",
        str(BIN / "navd"),
        "run",
        "--config",
        str(d / "navd.yaml"),
        "--site",
        str(site),
    ]
    navd = subprocess.Popen(command, stderr=stderr)
    spam: dict[str, int] = {}
    samples: dict[str, tuple[float, int]] = {}
    events: dict[str, dict] = {}
    pilot = None
    sampler = None
    try:
        time.sleep(5.0)
        pilot = _Autopilot(zport)
        time.sleep(55.0)
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
            elif f.device == "navd":
                _sleep_until(t0 + f.start)
                if "hung" in f.name:
                    navd.send_signal(signal.SIGSTOP)  # the loop stops: no WATCHDOG=1
                    time.sleep(6.0)  # WatchdogSec=5: systemd aborts it
                navd.kill()
                navd.wait()
                t_down = time.monotonic()
                time.sleep(2.0)  # RestartSec=2
                navd = subprocess.Popen(command, stderr=stderr)
                events[f.name] = {"t_down": t_down - t0, "t_restart": time.monotonic() - t0}
                # memory is compared within one process: the last one, from its first minute
                import threading

                if sampler is not None:
                    sampler.cancel()
                sampler = threading.Timer(60.0, _sample, (samples, navd.pid))
                sampler.start()
            elif f.device == "forge":
                _sleep_until(t0 + f.start)
                before = (pilot.forged, pilot.latest_forged)
                import threading

                asker = threading.Event()

                def ask(p=pilot, stop=asker) -> None:  # noqa: ANN001
                    while not stop.is_set():
                        p.ask_latest()
                        time.sleep(0.5)

                th = threading.Thread(target=ask, daemon=True)
                th.start()
                got = _forge(zport, f.end - f.start)
                asker.set()
                th.join(5)
                events[f.name] = {
                    **got,
                    "seen_by_autopilot": pilot.forged - before[0],
                    "latest_asked": pilot.latest_asked,
                    "latest_forged": pilot.latest_forged - before[1],
                }
            elif f.device == "flood":
                _sleep_until(t0 + f.start)
                events[f.name] = _flood(zport, f.end - f.start)
        _sleep_until(t0 + minutes * 60)
        samples["end"] = _rss_fds(navd.pid)
        if pilot is not None:
            events["autopilot"] = {
                "estimates": pilot.estimates,
                "forged": pilot.forged,
                "unavailable": [(round(t - t0, 1), w) for t, w in pilot.unavailable],
            }
        # what only this process saw, kept so that --summarise can report a kept run again
        (work / "samples.json").write_bytes(
            jsonlines.dumps(
                {"samples": samples, "spam": spam, "t0": t0, "spacing": spacing, "events": events}
            )
        )
        copy = work / "log"
        shutil.copytree(root / str(logdir).lstrip("/"), copy)
    finally:
        if pilot is not None:
            pilot.close()
        navd.send_signal(signal.SIGTERM)
        navd.wait(timeout=30)
        holder.kill()
        holder.wait(timeout=30)
        hil.send_signal(signal.SIGTERM)
        hil.wait(timeout=30)
        stderr.close()
        hil_err.close()
    return summarise(work, d, copy, scaled, t0, samples, spam, minutes, events)


def _sleep_until(t: float) -> None:
    time.sleep(max(0.0, t - time.monotonic()))


def _truth(d: Path) -> tuple[list[float], list[tuple[float, float]]]:
    ts, pos = [], []
    for line in (d / "truth.jsonl").read_text().splitlines():
        s = jsonlines.loads(line)
        ts.append(s["t"])
        pos.append((s["lat"], s["lon"]))
    return ts, pos


def _outside_99(est: dict, ts: list[float], pos: list[tuple[float, float]], t0: float) -> bool:
    """Whether the truth lies outside the estimate's 99 % ellipse."""
    import bisect

    from navd import geodesy

    t = est["t"] - t0
    i = min(len(ts) - 1, max(0, bisect.bisect_left(ts, t)))
    lat, lon = pos[i]
    e, n, _ = geodesy.enu_offset(
        math.radians(est["lat"]),
        math.radians(est["lon"]),
        0.0,
        math.radians(lat),
        math.radians(lon),
        0.0,
    )
    snn, see, sne = est["std_n"] ** 2, est["std_e"] ** 2, est.get("cov_ne", 0.0)
    det = snn * see - sne * sne
    if det <= 0:
        return True
    return (see * n * n - 2 * sne * n * e + snn * e * e) / det > CHI2_99


def _autopilot_rows(lines: list[dict], faults, t0: float, d: Path, events: dict) -> list[str]:  # noqa: ANN001
    """For each fault of what reaches the autopilot: estimates stopped, ok outside 99 %."""
    ts, pos = _truth(d)
    est = sorted((o for o in lines if o.get("type") == "estimate"), key=lambda o: o["t"])
    ok = [o for o in est if o.get("integrity") == "ok"]
    share = sum(_outside_99(o, ts, pos, t0) for o in ok) / max(1, len(ok))
    rows = [
        f"Over the whole run, {len(ok)} of {len(est)} estimates were marked ok, and "
        f"{100 * share:.2f} % of those had the truth outside their 99 % ellipse (a consistent "
        "filter: about 1 %).",
        "",
        "| fault | at (s) | estimates stopped for (s) | first estimate after the restart (s) "
        f"| ok estimates in the next {JUDGED_S:.0f} s | of them outside their 99 % ellipse | "
        "what the autopilot saw |",
        "|---|---|---|---|---|---|---|",
    ]
    times = [o["t"] - t0 for o in est]
    for f in faults:
        if f.device not in ("navd", "forge", "flood", "gps-glitch"):
            continue
        a, b = f.start, f.start + JUDGED_S
        inside = [t for t in times if a - 5.0 <= t <= f.end + 15.0]
        gaps = [y - x for x, y in zip(inside, inside[1:], strict=False)]
        stopped = max(gaps, default=math.nan)
        ev = events.get(f.name, {})
        first = "-"
        if "t_restart" in ev:
            after = [t for t in times if t >= ev["t_restart"]]
            first = f"{after[0] - ev['t_restart']:.1f}" if after else "never"
        judged = [o for o in ok if a <= o["t"] - t0 <= b]
        out = sum(_outside_99(o, ts, pos, t0) for o in judged)
        saw = {k: v for k, v in ev.items() if k not in ("t_down", "t_restart")}
        rows.append(
            f"| {f.name} | {f.start:.0f} | {stopped:.1f} | {first} | {len(judged)} | {out} | "
            f"{saw or '-'} |"
        )
    ap = events.get("autopilot")
    if ap:
        rows += [
            "",
            f"The autopilot's NavClient over the run: {ap['estimates']} estimates, "
            f"{ap['forged']} of them forged; told unavailable {len(ap['unavailable'])} times: "
            + "; ".join(f"{t:.0f} s {w}" for t, w in ap["unavailable"][:12]),
        ]
    return rows


def summarise(work, d, copy, faults, t0, samples, spam, minutes, events=None) -> str:  # noqa: ANN001
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
        t_said = said[0]["t"] - t0 - f.start if said else None
        after = [h for h in health if h["t"] - t0 >= f.end]
        t_ok = next((h["t"] - t0 - f.end for h in after if not _says(h, words)), None)
        late = t_said is None or t_said > f.end - f.start + 5
        said_s = "not said" if late else f"{t_said:.0f} s"
        ok_s = "-" if t_ok is None else f"{t_ok:.0f} s"
        rows.append(f"| {f.name} | {f.start:.0f} | {said_s} | {ok_s} |")
    check = replay_against_live(files, d / "navd.yaml", work / "replay.jsonl")
    rss0, fd0 = samples.get("start", (math.nan, 0))
    rss1, fd1 = samples.get("end", (math.nan, 0))
    rows_ap = _autopilot_rows(lines, faults, t0, d, events or {})
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
        f"- RSS {rss0:.1f} MB after the first minute (of the last daemon, after the restarts), "
        f"{rss1:.1f} MB at the end "
        f"(growth {rss1 - rss0:+.1f} MB, target < 10); open files {fd0} and {fd1}",
        f"- exceptions on the daemon's stderr: {exceptions}",
        f"- command spam: {spam}",
        f"- the whole log replayed: {check.common} of {check.live} estimates at the same times, "
        f"largest difference from the live ones {check.worst:.1e}",
        "",
        "| fault | at (s) | health said it after | health ok again after the fault |",
        "|---|---|---|---|",
        *rows,
        "",
        "What reaches the autopilot:",
        "",
        *rows_ap,
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
        work,
        work / "vehicle",
        work / "log",
        scaled,
        t0,
        samples,
        extra.get("spam", {}),
        minutes,
        extra.get("events", {}),
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
    spacing = "" if args.spacing == 40.0 else f" --spacing {args.spacing:g}"
    report(
        f"`python -m bench.soak --minutes {args.minutes:g}{spacing}`\n\n{body}",
        args.write,
        "bench-soak",
        "Soak",
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
