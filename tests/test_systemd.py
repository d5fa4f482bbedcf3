"""The unit file passes systemd-analyze; sd_notify reaches a real notify socket."""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from navd.daemon.sdnotify import Notifier

UNIT = Path(__file__).resolve().parent.parent / "systemd" / "navd.service"
needs_systemd = pytest.mark.skipif(
    shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed"
)


def _unit_here(tmp_path: Path) -> Path:
    # verify checks that ExecStart exists: point it at this checkout's navd
    navd = Path(sys.executable).parent / "navd"
    text = UNIT.read_text().replace("/opt/navd/.venv/bin/navd", str(navd))
    out = tmp_path / "navd.service"
    out.write_text(text)
    return out


@needs_systemd
def test_systemd_analyze_verify_accepts_the_unit(tmp_path: Path) -> None:
    r = subprocess.run(
        ["systemd-analyze", "verify", str(_unit_here(tmp_path))], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    assert "navd.service" not in r.stderr  # no warning about our own unit


@needs_systemd
def test_security_exposure_at_most_2(tmp_path: Path) -> None:
    r = subprocess.run(
        ["systemd-analyze", "security", "--offline=yes", str(_unit_here(tmp_path))],
        capture_output=True,
        text=True,
    )
    m = re.search(r"Overall exposure level for navd.service: ([0-9.]+)", r.stdout + r.stderr)
    assert m, r.stdout + r.stderr
    assert float(m.group(1)) <= 2.0


def test_unit_is_notify_with_watchdog_and_dialout() -> None:
    text = UNIT.read_text()
    for line in (
        "Type=notify",
        "WatchdogSec=",
        "Restart=on-failure",
        "SupplementaryGroups=dialout",
        "ProtectSystem=strict",
        "NoNewPrivileges=yes",
        "PrivateTmp=yes",
        "DeviceAllow=",
        "StateDirectory=navd",
        "LogsDirectory=navd",
        "ConfigurationDirectory=navd",
        "RestartPreventExitStatus=78",
    ):
        assert line in text


def test_sd_notify_datagrams(tmp_path: Path) -> None:
    path = tmp_path / "notify"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
        s.bind(str(path))
        n = Notifier({"NOTIFY_SOCKET": str(path), "WATCHDOG_USEC": "5000000"})
        assert n.watchdog_s == 5.0
        assert n.ready("navigating") and n.watchdog()
        assert s.recv(100) == b"READY=1\nSTATUS=navigating"
        assert s.recv(100) == b"WATCHDOG=1"
    assert not Notifier({}).ready()  # outside systemd: a no-op
