"""A restart while submerged: navd resumes from its checkpoint instead of going blind.

What a vehicle team relies on: when systemd restarts navd underwater (a crash, the
watchdog), estimates come back within seconds, honest about the time lost (the
covariance grown, integrity degraded until ranges confirm it), and a replay of the
logs across the restart gives what the daemon published.
"""

from __future__ import annotations

import math
import os
import signal
import time
from pathlib import Path

import pytest
from conftest import mission
from serialised import rows

from navd.analysis.replay import run_navigator
from navd.daemon.checkpoint import Checkpoints, config_digest
from navd.filter import Navigator
from navd.formats import jsonlines
from navd.formats.mlog import read_measurement_log, record_to_json
from navd.hil.bench_vehicle import BenchVehicle, log_objects, replay_against_live
from navd.hil.sim_cli import crew_config
from navd.records import Resume
from navd.settings import config_from_dict

HEADER = '{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T15:04:05Z"}\n'
T_KILL, T_BACK = 60.0, 62.5  # mission seconds: submerged from 30 to 100 in the demo


def _cfg():
    return config_from_dict(crew_config(mission("demo", 1).scenario))


def _resume_record(nav: Navigator, t: float, age: float) -> Resume:
    s = nav.snapshot()
    assert s is not None
    return Resume(
        t,
        s["mode"],
        tuple(s["x"]),
        tuple(s["P"]),
        age,
        s["surface_bar"],
        s["surface_alt"],
        s["depth_m"],
    )


def test_a_resumed_navigator_goes_on_honestly() -> None:
    recs = mission("demo", 1).records
    cfg = _cfg()
    before = Navigator(cfg)
    out_a: list[dict] = []
    for r in recs:
        if r.t > T_KILL:
            break
        out_a += before.feed(r)
    last = [o for o in rows(out_a) if o["type"] == "estimate"][-1]
    assert last["mode"] == "submerged"
    after = Navigator(cfg)
    res = _resume_record(before, T_BACK, T_BACK - T_KILL)
    assert after.feed(res) == [] and after.counters["resumed"] == 1
    out_b: list[dict] = []
    for r in recs:
        if r.t > T_BACK:
            out_b += after.feed(r)
    est = [o for o in rows(out_b) if o["type"] == "estimate"]
    assert est[0]["t"] - T_BACK < 0.2  # estimates at once, no GPS needed
    grown = math.hypot(last["std_n"], cfg.checkpoint.drift_mps * (T_BACK - T_KILL))
    assert est[0]["std_n"] == pytest.approx(grown, rel=0.1)
    assert est[0]["integrity"] == "degraded" and "resumed" in est[0]["integrity_reason"]
    accepted = [o["t"] for o in rows(out_b) if o["type"] == "range" and o["accepted"]]
    if len(accepted) >= 3:  # confirmed by ranges: no longer "resumed"
        later = [o for o in est if o["t"] > accepted[2] + 0.2]
        assert all("resumed" not in (o.get("integrity_reason") or "") for o in later)


def test_a_replay_across_the_restart_gives_the_resumed_estimates(tmp_path: Path) -> None:
    recs = mission("demo", 1).records
    cfg = _cfg()
    before = Navigator(cfg)
    lines = []
    for r in recs:
        if r.t > T_KILL:
            break
        before.feed(r)
        lines.append(jsonlines.dumps_line(record_to_json(r)))
    res = _resume_record(before, T_BACK, T_BACK - T_KILL)
    lines.append(jsonlines.dumps_line(record_to_json(res)))
    live = Navigator(cfg)
    live_out = live.feed(res)
    for r in recs:
        if r.t > T_BACK:
            lines.append(jsonlines.dumps_line(record_to_json(r)))
            live_out += live.feed(r)
    p = tmp_path / "two-runs.jsonl"
    p.write_text(HEADER + "".join(lines))
    log = read_measurement_log(p)
    assert not log.skipped
    replayed = run_navigator(log, cfg).outputs
    after = [o for o in rows(replayed) if o["type"] == "estimate" and o["t"] > T_KILL]
    live_est = [o for o in rows(live_out) if o["type"] == "estimate"]
    assert after and after[0]["t"] > T_BACK  # nothing made up for the time navd was down
    assert after[: len(live_est)] == live_est  # (replay also steps to the last record)


def _store(tmp_path: Path, vehicle: str = "690s", wall: float = 1000.0) -> Checkpoints:
    return Checkpoints(tmp_path, vehicle, config_digest(_cfg()), wall=lambda: wall)


def test_a_checkpoint_is_resumed_only_when_it_is_this_vehicles_and_young(tmp_path: Path) -> None:
    snap = {"mode": "default", "x": [0.6, -1.4] + [0.0] * 6, "P": [0.0] * 64}
    assert _store(tmp_path).write(snap)
    doc, why = _store(tmp_path, wall=1010.0).load(300.0)
    assert doc is not None and doc["age_s"] == pytest.approx(10.0) and why == ""
    assert "400 s old" in _store(tmp_path, wall=1400.0).load(300.0)[1]
    assert "another vehicle" in _store(tmp_path, vehicle="other").load(300.0)[1]
    other = Checkpoints(tmp_path, "690s", "0" * 16, wall=lambda: 1000.0)
    assert "another navigation config" in other.load(300.0)[1]
    (tmp_path / "checkpoint.json").write_bytes(b"\x00garbage")
    doc, why = _store(tmp_path).load(300.0)
    assert doc is None and "not JSON" in why and len(why.splitlines()) == 1
    (tmp_path / "checkpoint.json").unlink()
    os.mkfifo(tmp_path / "checkpoint.json")
    doc, why = _store(tmp_path).load(300.0)
    assert doc is None and "FIFO" in why
    assert _store(tmp_path / "none").load(300.0) == (None, "")


def test_a_restart_while_submerged_resumes_within_5_s_and_replays(tmp_path: Path) -> None:
    """kill -9 while submerged, started again as systemd would: the real daemon and emulators."""
    d = tmp_path / "vehicle"
    stderr = open(tmp_path / "navd.stderr", "w")  # noqa: SIM115 (the daemons', kept open)
    # with a tidal prediction whose clock the receiver corrects (tests/test_daemon.py): the
    # restarted daemon starts from the computer's clock again, and so must the replay
    tide = {"amplitude_mps": 0.05, "max_flood_utc": "2016-01-08T15:00:00Z"}
    v = BenchVehicle(
        d, navd_stderr=stderr, state_dir=tmp_path / "state", config={"navigation": {"tide": tide}}
    )
    try:
        while time.monotonic() - v.t0_monotonic < T_KILL:
            assert v.navd.poll() is None, (tmp_path / "navd.stderr").read_text()
            time.sleep(0.2)
        os.kill(v.navd.pid, signal.SIGKILL)
        v.navd.wait()
        time.sleep(2.0)  # RestartSec=2
        t_restart = time.monotonic()
        v.restart_navd()
        while time.monotonic() - v.t0_monotonic < 95.0:
            assert v.navd.poll() is None, (tmp_path / "navd.stderr").read_text()
            time.sleep(0.2)
        v.stop()
    finally:
        v.kill()
        stderr.close()
    first, second = v.logfiles()
    est2 = [o for o in log_objects(second) if o.get("type") == "estimate"]
    assert est2, (tmp_path / "navd.stderr").read_text()
    assert est2[0]["t"] - t_restart < 5.0  # estimates again within 5 s, still submerged
    assert est2[0]["mode"] == "submerged" and est2[0]["integrity"] != "ok"
    assert any(o.get("type") == "cmd_resume" for o in log_objects(second))
    check = replay_against_live([first, second], v.config, tmp_path / "replayed.jsonl")
    assert check.returncode == 0, check.stderr
    objs = [o for f in (first, second) for o in log_objects(f)]
    live_t = {o["t"] for o in objs if o.get("type") == "estimate"}
    replayed_t = {o["t"] for o in log_objects(tmp_path / "replayed.jsonl")}
    missing = sorted(live_t - replayed_t)
    tail = [o for o in log_objects(first)][-6:]
    assert check.common == check.live, (missing, t_restart, tail)
    assert check.worst < 1e-9

