"""The real daemon against the real emulators over pseudo-terminals, with real zenoh on loopback.

These tests take minutes of wall time: they run missions in real time.
"""

from __future__ import annotations

import json
import math
import os
import signal
import time
from dataclasses import replace
from pathlib import Path

import pytest
import zenoh

from navd.config import load_config
from navd.daemon.publish import zenoh_config
from navd.formats.jsonlines import read as read_jsonl
from navd.formats.mlog import read_measurement_log
from navd.hil.bench_vehicle import BenchVehicle, replay_against_live


class Mission:
    """navd-hil and navd run as the vehicle would run them, and a zenoh peer watching."""

    def __init__(self, d: Path, faults: list | None = None, config: dict | None = None) -> None:
        self.dir = d
        fault_file = None
        if faults:
            fault_file = d.parent / "faults.yaml"
            fault_file.write_text(json.dumps(faults))
        stderr = open(d.parent / "navd.stderr", "w")  # noqa: SIM115 (the daemon's, kept open)
        self.vehicle = BenchVehicle(d, navd_stderr=stderr, faults=fault_file, config=config)
        self.navd = self.vehicle.navd
        self.cfg = load_config(self.vehicle.config)
        self.t0 = self.vehicle.t0_monotonic
        zc = self.cfg.zenoh
        try:
            self.session = zenoh.open(zenoh_config(replace(zc, listen=[], connect=list(zc.listen))))
        except Exception:
            self.vehicle.kill()
            raise
        self.estimates: list[tuple[float, dict]] = []
        self.ranges: list[dict] = []
        self.health: list[dict] = []
        prefix = f"auv/{self.cfg.vehicle.name}/nav"
        self.prefix = prefix
        self._subs = [
            self.session.declare_subscriber(
                f"{prefix}/estimate",
                lambda s: self.estimates.append(
                    (time.monotonic(), json.loads(s.payload.to_bytes()))
                ),
            ),
            self.session.declare_subscriber(
                f"{prefix}/range", lambda s: self.ranges.append(json.loads(s.payload.to_bytes()))
            ),
            self.session.declare_subscriber(
                f"{prefix}/health", lambda s: self.health.append(json.loads(s.payload.to_bytes()))
            ),
        ]

    def mission_time(self) -> float:
        return time.monotonic() - self.t0

    def wait_mission(self, t: float) -> None:
        while self.mission_time() < t:
            assert self.navd.poll() is None, (self.dir.parent / "navd.stderr").read_text()
            time.sleep(0.2)

    def stop(self) -> None:
        self.vehicle.stop(timeout=20)
        self.session.close()

    def kill(self) -> None:
        self.vehicle.kill()
        self.session.close()


@pytest.fixture
def mission_dir(tmp_path: Path) -> Path:
    return tmp_path / "vehicle"


# A weak tidal prediction: the emulated receiver's UTC (2016) is years off the computer's,
# so the daemon must take the receiver's clock, and its replay the same from the log
TIDE = {"amplitude_mps": 0.05, "toward_deg": 30.0, "max_flood_utc": "2016-01-08T15:00:00Z"}


def test_live_mission_over_ptys_and_zenoh_replays_exactly(mission_dir: Path) -> None:
    m = Mission(mission_dir, config={"navigation": {"tide": TIDE}})
    try:
        # the operator resets the filter at the surface; the log keeps the command, so
        # the replay below only matches the live estimates if it re-applies it
        m.wait_mission(12.0)
        (ok,) = [
            json.loads(r.ok.payload.to_bytes()) for r in m.session.get(f"{m.prefix}/cmd/reset")
        ]
        assert ok == {"ok": True}
        m.wait_mission(75.0)
        # the autopilot's ways in: liveliness and the latest estimate
        alive = [r.ok.key_expr for r in m.session.liveliness().get(f"{m.prefix}/alive") if r.ok]
        assert [str(k) for k in alive] == [f"{m.prefix}/alive"]
        (latest,) = [
            json.loads(r.ok.payload.to_bytes()) for r in m.session.get(f"{m.prefix}/latest")
        ]
        assert latest["schema"] == 1 and math.isfinite(latest["lat"])
        # a malformed command is refused and changes nothing
        (bad,) = [
            json.loads(r.ok.payload.to_bytes())
            for r in m.session.get(f"{m.prefix}/cmd/beacon", payload=b'{"name":"x","lat":95}')
        ]
        assert bad["ok"] is False and ("lon" in bad["error"] or "lat" in bad["error"])
    finally:
        m.stop()

    # SIGTERM: exit 0, and one "stopped" line naming the log
    assert m.navd.returncode == 0
    said = (mission_dir.parent / "navd.stderr").read_text().splitlines()
    stopped = [line for line in said if "stopped; log " in line]
    assert len(stopped) == 1 and m.vehicle.logfile().name in stopped[0]
    # the observability advisory came once a second, in the log as on zenoh
    advisories = [o for o in read_jsonl(m.vehicle.logfile()) if o.get("type") == "advisory"]
    assert advisories and {a["verdict"] for a in advisories} <= {
        "ok",
        "weak_cross_range",
        "no_ranges",
    }

    # estimates at 10 Hz (+-5 %) over the last 50 s
    recv = [t for t, _ in m.estimates]
    window = [t for t in recv if t >= recv[-1] - 50.0]
    assert len(window) / (window[-1] - window[0]) == pytest.approx(10.0, rel=0.05)
    seqs = [e["seq"] for _, e in m.estimates]
    assert seqs == sorted(seqs)

    # a ping every 10 s, fused
    t_ranges = [r["t"] for r in m.ranges]
    assert len(m.ranges) >= 6
    gaps = [b - a for a, b in zip(t_ranges, t_ranges[1:], strict=False)]
    assert all(g == pytest.approx(10.0, abs=1.0) for g in gaps)
    assert sum(r["accepted"] for r in m.ranges) >= 3

    # health tells the truth: everything connected, nothing degraded
    last = m.health[-1]
    # every range the (paced, 9600-baud) modem delivered reached the filter: its location
    # line arrives after other sensors' records, and the range is still fused, late when
    # a tick fell inside the line (that path: tests/test_poisoned_inputs.py)
    assert last["pings"]["ranges"] >= 6
    assert last["pings"]["ranges"] - last["pings"]["fused"] <= 1  # one may be in flight
    assert all(d["connected"] for d in last["devices"].values())
    assert last["devices"]["ahrs"]["rate_hz"] == pytest.approx(20.0, rel=0.1)
    # the devices said who they are: the AHRS its firmware, the ESC its battery
    assert last["devices"]["ahrs"]["firmware"] == 1134
    assert last["devices"]["pressure"]["serial_number"] == 123456
    assert last["devices"]["ahrs"]["hard_iron"] == [0.0, 0.0, 0.0]  # never calibrated
    assert last["esc"]["battery_v"] == pytest.approx(14.8, abs=0.1)
    assert last["degraded"] == [] or all("integrity" in p for p in last["degraded"])
    # the tidal prediction reads the receiver's clock, not the computer's
    assert last["filter"]["tide_clock_corrected"] == 1

    # position against the simulator's truth, within the filter's own 3 sigma
    truth = {round(s["t"], 1): s for s in read_jsonl(mission_dir / "truth.jsonl")}
    from navd.analysis.score import _ne_error

    inside, n = 0, 0
    for _, e in m.estimates:
        if e["mode"] != "submerged":
            continue
        tr = truth.get(round(e["t"] - m.t0, 1))
        if tr is None:
            continue
        dn, de = _ne_error(e["lat"], e["lon"], tr["lat"], tr["lon"])
        n += 1
        inside += abs(dn) <= 3 * e["std_n"] and abs(de) <= 3 * e["std_e"]
    assert n > 300 and inside / n >= 0.95

    # live equals replay: the log replays to the same estimates to 1e-9
    (logfile,) = sorted((mission_dir / "log").glob("*.jsonl"))
    check = replay_against_live([logfile], mission_dir / "navd.yaml", mission_dir / "replay.jsonl")
    assert check.returncode == 0, check.stderr
    assert [o.get("type") for o in read_jsonl(logfile)].count("cmd_reset") == 1
    # the receiver's UTC, the tidal prediction's clock, is in the log for the replay
    clocks = [o for o in read_jsonl(logfile) if o.get("type") == "clock"]
    assert clocks and all(b["t"] - a["t"] >= 60.0 for a, b in zip(clocks, clocks[1:], strict=False))
    assert check.common >= check.live - 1
    assert check.worst <= 1e-9


def test_faults_on_every_port_and_the_daemon_keeps_navigating(mission_dir: Path) -> None:
    faults = [
        {"t": 12, "device": "gps", "action": "gps_off"},  # GPS drops out at the surface
        {"t": 15, "device": "modem", "action": "garbage", "value": 0.3},
        {"t": 28, "device": "modem", "action": "garbage", "value": 0.0},
        {"t": 20, "device": "gps", "action": "gps_on"},
        {"t": 22, "device": "modem", "action": "online"},  # a CONNECT: commands are data
        {"t": 25, "device": "pressure", "action": "power_blip"},  # forgets its F48
        {"t": 33, "device": "ahrs", "action": "reconnect"},  # the AHRS port vanishes
        {"t": 35, "device": "modem", "action": "drop_reply", "value": 1.0},  # UDB silent
        *[
            {"t": 36, "device": dev, "action": a, "value": 0.1}
            for dev in ("ahrs", "gps", "pressure", "motor")
            for a in ("garbage", "bad_checksum")
        ],
        {"t": 50, "device": "modem", "action": "drop_reply", "value": 0.0},
    ]
    m = Mission(mission_dir, faults)
    try:
        m.wait_mission(72.0)
        n_before = len(m.estimates)
        time.sleep(1.0)
        assert len(m.estimates) >= n_before + 8  # still publishing
    finally:
        m.stop()
    h = m.health[-1]
    dev = h["devices"]
    assert dev["ahrs"]["reconnects"] >= 1 and dev["ahrs"]["connected"]
    for name in ("ahrs", "gps", "pressure", "motor"):
        assert dev[name]["bad_checksum"] + dev[name]["skipped_bytes"] > 0, name
    assert h["pings"]["timeouts"] + h["pings"]["no_reply"] >= 1
    # the pressure sensor said "not initialised" and was initialised again: depth is fresh
    assert dev["pressure"]["device_errors"] >= 1 and h["input_age_s"]["depth"] < 1.0
    # the modem started online and fell online again: brought back to command mode both times
    assert h["modem"]["ready"] and h["modem"]["escapes"] >= 2
    # the filter recovers: ranges accepted again after the UDB comes back
    late = [
        (round(r["t"] - m.t0), r["accepted"], r["reason"], r.get("residual_m"), r.get("gate_m"))
        for r in m.ranges
    ]
    assert any(r["accepted"] for r in m.ranges if r["t"] - m.t0 > 50), (late, h["pings"])
    assert all(math.isfinite(e["lat"]) for _, e in m.estimates)


def test_log_survives_kill_9(mission_dir: Path) -> None:
    m = Mission(mission_dir)
    try:
        m.wait_mission(10.0)
        t_kill = time.monotonic()
        os.kill(m.navd.pid, signal.SIGKILL)
        m.navd.wait()
    finally:
        m.kill()
    (logfile,) = sorted((mission_dir / "log").glob("*.jsonl"))
    log = read_measurement_log(logfile)  # a torn last line would be skipped and counted
    assert len(log.skipped) <= 1
    assert max(r.t for r in log.records) >= t_kill - 1.0
