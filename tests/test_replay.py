"""navd replay per the contract: formats, errors, smoothing, determinism."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import mission
from serialised import rows

from navd.analysis.score import score
from navd.formats.jsonlines import read as read_jsonl
from navd.formats.outputs import read_outputs
from navd.formats.truth import TruthSample, read_truth
from navd.hil.sim_cli import write_mission
from navd.schema import Estimate

NAVD = [sys.executable, "-m", "navd.cli"]
HEADER = '{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T15:04:05Z"}\n'


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*NAVD, *args], capture_output=True, text=True, timeout=300)


def replay_claytor(d: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return run(
        "replay",
        str(d / "measurements.jsonl"),
        "--config",
        str(d / "config.yaml"),
        "--out",
        str(out),
        *extra,
    )


@pytest.fixture(scope="module")
def claytor(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("claytor2")
    write_mission(mission("claytor-2", 7), d)
    return d


def test_replay_writes_estimates_at_10hz_and_range_decisions(claytor: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.jsonl"
    r = replay_claytor(claytor, out)
    assert r.returncode == 0, r.stderr
    rows = read_jsonl(out)
    est = [o for o in rows if o["type"] == "estimate"]
    rng = [o for o in rows if o["type"] == "range"]
    for key in ("t", "lat", "lon", "depth", "current_n", "current_e", "std_n", "std_e", "mode"):
        assert all(key in o for o in est)
    assert {o["mode"] for o in est} >= {"surface", "submerged"}
    dts = {round(b["t"] - a["t"], 6) for a, b in zip(est, est[1:], strict=False)}
    assert dts == {0.1}
    assert rng and all(
        {"beacon", "accepted", "residual_m", "gate_m", "reason"} <= o.keys() for o in rng
    )
    assert sum(o["accepted"] for o in rng) > len(rng) / 2
    assert all(math.isfinite(v) for o in est for v in o.values() if isinstance(v, float))


def test_replay_is_deterministic(claytor: Path, tmp_path: Path) -> None:
    outs = []
    for i in range(2):
        out = tmp_path / f"o{i}.jsonl"
        replay_claytor(claytor, out)
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]


def test_filter_beats_dead_reckoning_and_smoother_beats_filter(
    claytor: Path, tmp_path: Path
) -> None:
    truth = read_truth(claytor / "truth.jsonl")
    assert replay_claytor(claytor, tmp_path / "f.jsonl").returncode == 0
    assert replay_claytor(claytor, tmp_path / "s.jsonl", "--smooth").returncode == 0
    filt = score(read_outputs(tmp_path / "f.jsonl"), truth)
    smoothed = read_outputs(tmp_path / "s.jsonl")
    assert all(o.smoothed for o in smoothed if isinstance(o, Estimate))
    smooth = score(smoothed, truth)
    assert smooth.rms_m < filt.rms_m
    assert filt.rms_m < 25.0


def test_missing_file_is_one_line_exit_2(tmp_path: Path) -> None:
    r = run("replay", str(tmp_path / "nope.jsonl"), "--out", str(tmp_path / "o.jsonl"))
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "nope.jsonl" in r.stderr and "Traceback" not in r.stderr


def test_malformed_lines_are_skipped_and_reported_with_numbers(tmp_path: Path) -> None:
    log = tmp_path / "m.jsonl"
    log.write_text(
        HEADER
        + '{"type":"gps","t":0,"lat":37.05,"lon":-80.66,"alt":530,"fix":1}\n'
        + '{"type":"heading","t":0.1,"deg":"north"}\n'  # line 3: wrong type
        + "not json\n"  # line 4
        + '{"type":"depth","t":0.2,"m":NaN}\n'  # line 5: NaN
        + '{"type":"rpm","t":0.3,"rpm":900}\n'
    )
    out = tmp_path / "o.jsonl"
    r = run("replay", str(log), "--out", str(out))
    assert r.returncode == 0
    for n in (3, 4, 5):
        assert f"line {n}:" in r.stderr
    assert "3 lines skipped" in r.stderr
    strict = run("replay", str(log), "--out", str(out), "--strict")
    assert strict.returncode == 2
    assert "line 3" in strict.stderr and strict.stderr.count("\n") == 1


def test_bad_config_key_names_the_key(claytor: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("navigation:\n  speed:\n    rpm_per_mps: -3\n")
    r = run(
        "replay",
        str(claytor / "measurements.jsonl"),
        "--config",
        str(cfg),
        "--out",
        str(tmp_path / "o.jsonl"),
    )
    assert r.returncode == 2
    assert "navigation.speed.rpm_per_mps" in r.stderr and r.stderr.count("\n") == 1
    cfg.write_text("navigation:\n  rate_hz: 10\n  magic: 1\n")
    r = run("check-config", str(cfg))
    assert r.returncode == 2 and "navigation.magic: unknown key" in r.stderr


def test_check_config_accepts_the_shipped_config() -> None:
    root = Path(__file__).resolve().parent.parent
    r = run("check-config", str(root / "config" / "navd.yaml"))
    assert r.returncode == 0, r.stderr
    assert "ok" in r.stdout


def test_report_writes_figures(claytor: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.jsonl"
    replay_claytor(claytor, out)
    r = run(
        "report",
        str(out),
        "--truth",
        str(claytor / "truth.jsonl"),
        "--log",
        str(claytor / "measurements.jsonl"),
        "--out",
        str(tmp_path / "rep"),
    )
    assert r.returncode == 0, r.stderr
    for name in ("track.png", "ranges.png", "current_uncertainty.png", "summary.txt"):
        assert (tmp_path / "rep" / name).stat().st_size > 1000 or name == "summary.txt"
    assert "error at surfacing" in (tmp_path / "rep" / "summary.txt").read_text()
    # a --truth that is not the simulator's truth is blamed by name, in one line
    r = run("report", str(out), "--truth", str(out), "--out", str(tmp_path / "rep2"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1 and f"{out}: line 1 is not a truth sample" in r.stderr


def test_travel_time_records_with_fixed_beacon(tmp_path: Path) -> None:
    """A raw travel time and a beacon known only from config reach the filter."""
    log = tmp_path / "tt.jsonl"
    lines = [HEADER.strip()]
    for k in range(50):
        lines.append(
            json.dumps(
                {"type": "gps", "t": k * 0.1, "lat": 37.05, "lon": -80.66, "alt": 0.0, "fix": 1}
            )
        )
    # beacon 150 m due north of the vehicle, fresh water at 10 degC: c = 1447.3 m/s
    lines.append(
        json.dumps(
            {
                "type": "travel_time",
                "t": 5.0,
                "t_ping": 4.8,
                "twtt_s": 2 * 150.0 / 1447.3 + 0.1,
                "beacon": "lbl1",
            }
        )
    )
    log.write_text("\n".join(lines) + "\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(
        "beacons:\n  lbl1:\n    lat: 37.0513486\n    lon: -80.66\n    depth: 0.0\n"
        "    turnaround_s: 0.1\n"
    )
    out = tmp_path / "o.jsonl"
    r = run("replay", str(log), "--config", str(cfg), "--out", str(out))
    assert r.returncode == 0, r.stderr
    (rng,) = [o for o in read_jsonl(out) if o["type"] == "range"]
    assert rng["accepted"] and abs(rng["residual_m"]) < 1.0


def test_long_silence_restarts_at_the_next_fix() -> None:
    """A log with an hour-long hole gives no ticks inside the hole and re-initialises on GPS."""
    from navd.filter import Navigator
    from navd.records import Gps, Heading
    from navd.settings import config_from_dict

    nav = Navigator(config_from_dict({}))
    out = []
    for k in range(20):
        out += nav.feed(Gps(k * 0.1, 37.05, -80.66, 0.0, 1))
    out += nav.feed(Heading(3600.0, 10.0))  # nothing at all for an hour
    out += nav.feed(Gps(3600.5, 37.06, -80.66, 0.0, 1))
    out += nav.advance(3601.0)
    est = [o for o in rows(out) if o["type"] == "estimate"]
    assert not [o for o in est if 2.0 < o["t"] < 3600.5]
    assert nav.counters["restarts_after_gap"] == 1
    assert est[-1]["lat"] == pytest.approx(37.06, abs=1e-6)


def test_depth_from_pressure_zeroed_at_the_surface() -> None:
    """Pressure read while GPS has a fix is the surface; depth is measured from it."""
    from navd.filter import Navigator
    from navd.records import Gps, Pressure
    from navd.settings import config_from_dict

    nav = Navigator(config_from_dict({"site": {"water_density_kgm3": 1000.0}}))
    for k in range(10):  # a high-pressure day: 1.030 bar at the surface
        nav.feed(Gps(k * 0.1, 37.05, -80.66, 0.0, 1))
        nav.feed(Pressure(k * 0.1 + 0.05, 1.030))
    out = nav.feed(Pressure(10.0, 1.030 + 0.0980665))  # 1 m of fresh water, GPS long gone
    out += nav.advance(10.0)
    assert isinstance(out[-1], Estimate) and out[-1].depth == pytest.approx(1.0, abs=1e-6)


def test_operator_commands_in_the_log_are_replayed(tmp_path: Path) -> None:
    """cmd_beacon gives a position-less beacon its place (keeping its configured
    turnaround); cmd_reset forgets the estimate until the next GPS fix, as live."""
    log = tmp_path / "cmd.jsonl"
    gps = {"type": "gps", "lat": 37.05, "lon": -80.66, "alt": 0.0, "fix": 1}
    lines = [HEADER.strip()]
    lines += [json.dumps({**gps, "t": k * 0.1}) for k in range(50)]
    # the operator tells navd where lbl1 is: 150 m due north, at the surface
    lines.append(
        json.dumps(
            {"type": "cmd_beacon", "t": 4.9, "beacon": "lbl1", "lat": 37.0513486, "lon": -80.66}
        )
    )
    tt = {"type": "travel_time", "t": 5.0, "t_ping": 4.8, "beacon": "lbl1"}
    lines.append(json.dumps({**tt, "twtt_s": 2 * 150.0 / 1447.3 + 0.1}))
    lines.append(json.dumps({"type": "cmd_reset", "t": 6.0}))
    lines.append(json.dumps({"type": "heading", "t": 9.0, "deg": 0.0}))  # no estimate
    lines += [json.dumps({**gps, "t": 10.0 + k * 0.1}) for k in range(10)]  # new start
    log.write_text("\n".join(lines) + "\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text("beacons:\n  lbl1:\n    turnaround_s: 0.1\n")
    out = tmp_path / "o.jsonl"
    r = run("replay", str(log), "--config", str(cfg), "--out", str(out))
    assert r.returncode == 0, r.stderr
    outs = read_jsonl(out)
    (rng,) = [o for o in rows(outs) if o["type"] == "range"]
    assert rng["accepted"] and abs(rng["residual_m"]) < 1.0  # turnaround kept
    ticks = [o["t"] for o in rows(outs) if o["type"] == "estimate"]
    assert max(t for t in ticks if t < 10.0) <= 6.0 and max(ticks) > 10.0


def test_a_bad_command_record_names_its_line(tmp_path: Path) -> None:
    log = tmp_path / "bad.jsonl"
    bad = {"type": "cmd_beacon", "t": 1.0, "beacon": "lbl1", "lat": 95.0, "lon": 0.0}
    log.write_text(HEADER + json.dumps(bad) + "\n")
    out = tmp_path / "o.jsonl"
    r = run("replay", str(log), "--out", str(out))
    assert "line 2" in r.stderr and "lat" in r.stderr and "Traceback" not in r.stderr


def test_the_truth_is_matched_between_its_steps(claytor: Path, tmp_path: Path) -> None:
    """Live, the daemon's ticks fall between the simulator's steps: the report still
    compares, by interpolation; and says so plainly when nothing could be matched."""
    from navd.analysis.score import TruthAt

    at = TruthAt([TruthSample(0.0, 1.0, 2.0, 0.0, 90.0, 1.0, 0.0, 0.0, 1.0, 2.0),
                  TruthSample(0.1, 1.1, 2.2, 1.0, 91.0, 1.0, 0.1, 0.0, 1.0, 2.0),
                  TruthSample(5.0, 9.0, 9.0, 1.0, 92.0, 1.0, 0.0, 0.0, 1.0, 2.0)])  # fmt: skip
    mid = at(0.05)
    assert mid is not None and mid.lat == pytest.approx(1.05) and mid.depth == 0.5
    assert mid.current_n == pytest.approx(0.05) and mid.heading_deg == 90.0
    assert at(2.0) is None and at(-1.0) is None  # a gap in the truth, and before it
    out = tmp_path / "out.jsonl"
    replay_claytor(claytor, out)
    samples = [json.loads(x) for x in (claytor / "truth.jsonl").read_text().splitlines()]

    def moved(name: str, dt: float) -> Path:
        p = tmp_path / name
        p.write_text("".join(json.dumps({**s, "t": s["t"] + dt}) + "\n" for s in samples))
        return p

    shifted, far = moved("truth.jsonl", 0.037), moved("far.jsonl", 1e6)
    for truth, said in ((shifted, "against the truth, submerged: RMS"), (far, "no submerged")):
        r = run("report", str(out), "--truth", str(truth), "--out", str(tmp_path / "rep"))
        assert r.returncode == 0, r.stderr
        assert said in (tmp_path / "rep" / "summary.txt").read_text()


def test_a_gated_range_says_its_nis_and_a_range_that_never_reached_the_gate_does_not(
    claytor: Path, tmp_path: Path
) -> None:
    """``nis`` is the residual squared over the variance the gate used: with the default
    gate (9 short, 4 long, on that ratio) it is the residual over the gate, squared, times
    the side's chi-square."""
    out = tmp_path / "out.jsonl"
    assert replay_claytor(claytor, out).returncode == 0
    rng = [o for o in read_jsonl(out) if o["type"] == "range"]
    gated = [o for o in rng if o["reason"] in ("ok", "gate", "gate_reacquire")]
    assert len(gated) > 20 and any(not o["accepted"] for o in gated)
    for o in gated:
        chi2 = 4.0 if o["residual_m"] > 0.0 else 9.0
        assert o["nis"] == pytest.approx(chi2 * (o["residual_m"] / o["gate_m"]) ** 2, rel=1e-6)
        assert (o["nis"] <= chi2) == o["accepted"] or o["reason"] == "gate_reacquire"
    assert all("nis" not in o for o in rng if o["residual_m"] is None)
