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
