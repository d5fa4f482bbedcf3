"""The command line's conventions: ``python -m navd``, ``--version``, usage without a command."""

from __future__ import annotations

import subprocess
import sys


def _navd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "navd", *args], capture_output=True, text=True, check=False
    )


def test_no_command_prints_the_commands() -> None:
    r = _navd()
    assert r.returncode == 2 and "Traceback" not in r.stderr
    for cmd in ("run", "replay", "report", "watch", "capture", "calibrate", "check-config"):
        assert cmd in r.stdout


def test_version() -> None:
    r = _navd("--version")
    assert r.returncode == 0 and r.stdout.startswith("navd ")


def _config_with_missing_ports(tmp_path) -> object:
    import socket

    import yaml

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    devices = {
        n: {"port": str(tmp_path / f"no-{n}")}
        for n in ("ahrs", "gps", "pressure", "motor", "modem")
    }
    cfg = tmp_path / "navd.yaml"
    cfg.write_text(
        yaml.safe_dump(
            {
                "devices": devices,
                "log": {"dir": str(tmp_path / "log")},
                "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
            }
        )
    )
    return cfg


def test_under_systemd_every_line_has_its_journal_priority_and_closed_ports_say_why(
    tmp_path,
) -> None:
    """`journalctl -p warning -u navd` finds what a crew needs: each port that did not open."""
    import os
    import signal
    import time

    cfg = _config_with_missing_ports(tmp_path)
    env = {**os.environ, "JOURNAL_STREAM": "8:12345"}
    p = subprocess.Popen(
        [sys.executable, "-m", "navd", "run", "--config", str(cfg)],
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    lines: list[str] = []
    assert p.stderr is not None
    t_end = time.monotonic() + 30
    while time.monotonic() < t_end:
        line = p.stderr.readline()
        if not line:
            break
        lines.append(line.rstrip("\n"))
        if "navd running" in line:
            break
    p.send_signal(signal.SIGTERM)
    _, rest = p.communicate(timeout=30)
    lines += [x for x in rest.splitlines() if x]
    assert lines and all(x[:1] == "<" and x[2] == ">" for x in lines), lines
    warnings = [x for x in lines if x.startswith("<4>")]
    for n in ("ahrs", "gps", "pressure", "motor", "modem"):
        (w,) = [x for x in warnings if f"navd: {n}: not open (" in x]
        assert "No such file" in w or "could not open" in w, w


def test_capture_of_a_port_that_cannot_open_says_why(tmp_path) -> None:
    cfg = _config_with_missing_ports(tmp_path)
    r = _navd(
        "capture", "gps", "--config", str(cfg), "--seconds", "1", "--out", str(tmp_path / "c")
    )
    assert r.returncode == 2
    assert "devices.gps.port" in r.stderr and "no-gps" in r.stderr
