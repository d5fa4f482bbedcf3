"""Hostile and unlucky files: a config or a log never hangs navd, leaks a file, or loses
a mission.

What users rely on: whatever file a config names, and whatever a log holds, navd
answers in one line naming the file and the problem (never its contents), in time
proportional to the file, and a corrupt line costs that line, not the mission.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import mission
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from navd.analysis.replay import run_navigator
from navd.config import load_config
from navd.formats import jsonlines
from navd.formats.mlog import HOLD_LINES, LogError, read_measurement_log, record_to_json
from navd.hil.mutate import JUMPS, KINDS, mutate, set_t
from navd.records import MAX_BEACONS, SetBeacon
from navd.schema import split_outputs
from navd.settings import ConfigError, config_from_dict

HEADER = '{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T15:04:05Z"}\n'
SECRET = "root:*:20228:0:99999:7:::\ndaemon:*:20228:0:99999:7:::\n"


# -- config ------------------------------------------------------------------------------
def _overlay(tmp_path: Path, target: str) -> Path:
    cfg = tmp_path / "navd.yaml"
    cfg.write_text(f"overlays: [{target}]\n")
    return cfg


def test_an_overlay_naming_a_secret_never_prints_it(tmp_path: Path) -> None:
    secret = tmp_path / "shadow"
    secret.write_text(SECRET)
    with pytest.raises(ConfigError) as exc:
        load_config(_overlay(tmp_path, str(secret)))
    msg = str(exc.value)
    assert "unknown key" in msg and len(msg.splitlines()) == 1
    assert "99999" not in msg and "daemon" not in msg  # at most a short excerpt of the key


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom", "/dev/null"])
def test_an_overlay_naming_a_device_is_refused_at_once(tmp_path: Path, device: str) -> None:
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match="character device, not a regular file"):
        load_config(_overlay(tmp_path, device))
    assert time.perf_counter() - t0 < 1.0


def test_an_overlay_naming_a_fifo_does_not_hang(tmp_path: Path) -> None:
    fifo = tmp_path / "site.yaml"
    os.mkfifo(fifo)
    cfg = _overlay(tmp_path, "site.yaml")
    r = subprocess.run(
        [sys.executable, "-m", "navd", "check-config", "--offline", str(cfg)],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 2 and "a FIFO, not a regular file" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_a_directory_as_config_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="a directory, not a regular file"):
        load_config(tmp_path)


def test_yaml_nested_3000_deep_is_one_line(tmp_path: Path) -> None:
    cfg = tmp_path / "deep.yaml"
    cfg.write_text("navigation: " + "[" * 3000 + "]" * 3000 + "\n")
    with pytest.raises(ConfigError, match="nested deeper than"):
        load_config(cfg)


def test_a_5000_digit_integer_names_its_key(tmp_path: Path) -> None:
    cfg = tmp_path / "n.yaml"
    cfg.write_text("navigation:\n  max_gap_s: " + "9" * 5000 + "\n")
    with pytest.raises(ConfigError) as exc:
        load_config(cfg)
    msg = str(exc.value)
    assert "navigation.max_gap_s: an integer of 5000 digits" in msg and len(msg) < 200


def test_an_alias_bomb_split_between_config_and_overlay_is_refused_quickly(tmp_path: Path) -> None:
    # 1.4 kB: nine levels of nine references, the last level in the overlay
    levels = ["x0: &a0 {" + ", ".join(f"k{i}: 1" for i in range(9)) + "}"]
    for n in range(1, 8):
        levels.append(f"x{n}: &a{n} {{" + ", ".join(f"k{i}: *a{n - 1}" for i in range(9)) + "}")
    (tmp_path / "base.yaml").write_text("\n".join(levels) + "\n")
    (tmp_path / "navd.yaml").write_text("overlays: [base.yaml]\n" + "x7: {k0: {k0: {k0: 2}}}\n")
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match="aliases repeated too often"):
        load_config(tmp_path / "navd.yaml")
    assert time.perf_counter() - t0 < 2.0


def test_overlays_merge_in_time_proportional_to_their_size(tmp_path: Path) -> None:
    # shared mappings under many keys, within the expansion bound: merged once per path
    doc = "shared: &s {" + ", ".join(f"k{i}: {{v: 1}}" for i in range(50)) + "}\n"
    doc += "".join(f"c{i}: *s\n" for i in range(300))
    (tmp_path / "base.yaml").write_text(doc)
    (tmp_path / "navd.yaml").write_text("overlays: [base.yaml, base.yaml, base.yaml]\n")
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match="unknown key"):  # merged, then refused by schema
        load_config(tmp_path / "navd.yaml")
    assert time.perf_counter() - t0 < 2.0


# -- logs ----------------------------------------------------------------------------------
def _mission_lines() -> list[str]:
    """The demo mission as a daemon would log it: measurements and a tick every 0.1 s."""
    m = mission("demo", 1)
    out: list[str] = []
    k = 1
    for rec in m.records:
        while k * 0.1 < rec.t:
            out.append(jsonlines.dumps_line({"type": "estimate", "t": round(k * 0.1, 9)}))
            k += 1
        out.append(jsonlines.dumps_line(record_to_json(rec)))
    return out


def _write(tmp_path: Path, lines: list[str] | bytes, name: str = "log.jsonl") -> Path:
    p = tmp_path / name
    if isinstance(lines, bytes):
        p.write_bytes(HEADER.encode() + lines)
    else:
        p.write_text(HEADER + "".join(lines))
    return p


def _replay(p: Path) -> tuple[list, list]:
    log = read_measurement_log(p)
    cfg = config_from_dict({"beacons": {"udb": {"depth": 1.0}}})
    res = run_navigator(log, cfg)
    return log.records, res.outputs


def _measurement_indices(lines: list[str]) -> list[int]:
    return [i for i, ln in enumerate(lines) if '"estimate"' not in ln]


def test_two_lines_far_in_the_future_cost_only_themselves(tmp_path: Path) -> None:
    lines = _mission_lines()
    clean, _ = _replay(_write(tmp_path, lines, "clean.jsonl"))
    i = _measurement_indices(lines)[len(lines) // 3]
    bad = list(lines)
    bad[i] = set_t(bad[i], 1e6)
    bad[i + 1] = set_t(bad[i + 1], 1e6 + 0.1)
    log = read_measurement_log(_write(tmp_path, bad))
    assert len(log.skipped) == 2 and len(log.records) == len(clean) - 2


@pytest.mark.parametrize("ahead", [100.0, 1e4, 1e9])
def test_a_tick_far_in_the_future_loses_nothing_and_does_not_hang(
    tmp_path: Path, ahead: float
) -> None:
    lines = _mission_lines()
    clean_recs, clean_out = _replay(_write(tmp_path, lines, "clean.jsonl"))
    ticks = [i for i, ln in enumerate(lines) if '"estimate"' in ln]
    i = ticks[len(ticks) // 2]
    bad = list(lines)
    bad[i] = set_t(bad[i], min(1e9, jsonlines.loads(bad[i])["t"] + ahead))
    t0 = time.perf_counter()
    recs, out = _replay(_write(tmp_path, bad))
    assert time.perf_counter() - t0 < 30.0
    assert len(recs) == len(clean_recs) - 1  # only the tick
    est, ranges = split_outputs(out)
    clean_est, clean_ranges = split_outputs(clean_out)
    assert sum(r.accepted for r in ranges) == sum(r.accepted for r in clean_ranges)
    assert abs(len(est) - len(clean_est)) <= 1


def test_an_invalid_utf8_byte_costs_its_line(tmp_path: Path) -> None:
    lines = _mission_lines()
    raw = "".join(lines).encode()
    k = raw.index(b"\n", len(raw) // 2) + 1
    bad = raw[: k + 5] + b"\xff\xfe" + raw[k + 5 :]
    p = _write(tmp_path, bad)
    log = read_measurement_log(p)
    (skip,) = log.skipped
    assert skip.reason == "invalid UTF-8"
    assert skip.line == raw[:k].count(b"\n") + 2  # the header is line 1
    clean = read_measurement_log(_write(tmp_path, raw, "clean.jsonl"))
    assert len(log.records) == len(clean.records) - 1  # that line, a tick or a measurement
    with pytest.raises(LogError, match=f"line {skip.line}: invalid UTF-8"):
        read_measurement_log(p, strict=True)


def test_beacon_commands_in_a_log_have_the_live_limits_in_linear_time(tmp_path: Path) -> None:
    lines = [
        jsonlines.dumps_line(record_to_json(SetBeacon(1.0 + k * 1e-4, f"b{k}", 37.0, -80.0)))
        for k in range(100_000)
    ]
    lines.insert(
        50,
        jsonlines.dumps_line(
            {"type": "cmd_beacon", "t": 1.00495, "beacon": "a b", "lat": 37.0, "lon": -80.0}
        ),
    )
    t0 = time.perf_counter()
    log = read_measurement_log(_write(tmp_path, lines))
    res = run_navigator(log, config_from_dict({}))
    assert time.perf_counter() - t0 < 20.0
    assert res.counters["beacon_commands_refused_limit"] == 100_000 - MAX_BEACONS
    # a name the live command would refuse is refused by the log reader
    assert any("beacon" in s.reason for s in log.skipped)


# -- random mutations of a real log ----------------------------------------------------
_LINES = None
_CLEAN: tuple[list, float] | None = None


def _clean_replay(tmp: Path) -> tuple[list, float]:
    global _CLEAN
    if _CLEAN is None:
        p = _write(tmp, _base(), "clean.jsonl")
        t0 = time.perf_counter()
        recs, _ = _replay(p)
        _CLEAN = (recs, time.perf_counter() - t0)
    return _CLEAN


def _base() -> list[str]:
    global _LINES
    if _LINES is None:
        _LINES = _mission_lines()[:2500]
    return _LINES


_MUTATION = st.tuples(
    st.sampled_from(KINDS), st.floats(0.0, 1.0), st.integers(0, 255), st.sampled_from(JUMPS)
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(muts=st.lists(_MUTATION, min_size=1, max_size=4))
def test_mutated_logs_never_raise_never_hang_and_lose_only_what_they_touch(tmp_path_factory, muts):
    tmp = tmp_path_factory.mktemp("mut")
    lines = _base()
    clean, t_clean = _clean_replay(tmp)
    data, touched = mutate(lines, muts)
    p = _write(tmp, data)
    t0 = time.perf_counter()
    recs, _ = _replay(p)
    assert time.perf_counter() - t0 < 2.0 * t_clean + 1.0
    kept = {(type(r).__name__, r.t) for r in recs}
    lost = sum(1 for r in clean if (type(r).__name__, r.t) not in kept)
    assert lost <= touched + HOLD_LINES * len(muts)


def _tiny_log(path: Path) -> Path:
    lines = [{"format": "navd-measurements", "version": 1, "start_utc": "2016-01-08T15:04:05Z"}]
    lines += [
        {"type": "gps", "t": 0.5 * k, "lat": 37.05, "lon": -80.66, "alt": 0.0, "fix": 1}
        for k in range(20)
    ]
    path.write_text("".join(jsonlines.dumps_line(o) for o in lines))
    return path


def test_replay_writes_into_a_device_or_a_pipe_and_never_over_it(tmp_path: Path) -> None:
    """`--out /dev/null` (here through a link to it) or a FIFO is written as it is: a file
    renamed over it would replace it, and as root that replaced /dev/null itself."""
    import stat
    import threading

    from navd.analysis.replay import replay

    log = _tiny_log(tmp_path / "m.jsonl")
    sink = tmp_path / "sink"
    sink.symlink_to("/dev/null")
    replay(log, config_from_dict({}), sink, err=open(os.devnull, "w"))  # noqa: SIM115
    assert sink.is_symlink() and os.readlink(sink) == "/dev/null"
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert not (tmp_path / "sink.part").exists()

    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(pipe.read_bytes()), daemon=True)
    reader.start()
    replay(log, config_from_dict({}), pipe, err=open(os.devnull, "w"))  # noqa: SIM115
    reader.join(timeout=30)
    assert stat.S_ISFIFO(os.lstat(pipe).st_mode)
    assert got and b"estimate" in got[0]  # the pipe's reader had the outputs
