"""The daemon's log: rotation, a failing disk, and what replay makes of it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from navd.formats.log import RecordLog
from navd.formats.mlog import read_measurement_log
from navd.records import Gps, Heading
from navd.settings import ConfigError, check_for_run, config_from_dict


def test_rotates_by_size_and_every_file_is_a_measurement_log(tmp_path: Path) -> None:
    log = RecordLog(tmp_path, rotate_mb=0.01)  # about 10 kB per file
    for k in range(2000):
        log.record(Heading(k * 0.1, 90.0))
        log.raw_bytes(k * 0.1, "ahrs", b"\xce\x00\x01")
    log.close()
    files = sorted(tmp_path.glob("*.jsonl"))
    assert len(files) >= 5
    heads = [read_measurement_log(f) for f in files]
    assert all(not h.skipped for h in heads)
    assert sum(len(h.records) for h in heads) == 2000
    assert all(h.header["time_base"] == "monotonic" for h in heads)
    # the rotated files replay as one mission
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "navd.cli",
            "replay",
            *map(str, files),
            "--out",
            str(tmp_path / "out.jsonl"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "replayed 2000 records (0 lines skipped)" in r.stderr


def test_failing_disk_degrades_logging_and_counts(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    log = RecordLog(blocker / "log")  # cannot create the directory
    log.record(Gps(0.0, 37.0, -80.0, 0.0, 1))
    log.record(Heading(0.1, 10.0))
    assert log.degraded and log.errors == 1 and log.dropped == 2
    assert "NotADirectoryError" in log.last_error or "FileExistsError" in log.last_error


def test_full_disk_mid_run(tmp_path: Path) -> None:
    log = RecordLog(tmp_path)
    log.record(Heading(0.0, 1.0))
    log.fh.close()  # the file goes away under us, as on a failing card
    log.record(Heading(0.1, 1.0))
    log.flush()
    assert log.degraded and log.errors >= 1


def test_navd_run_names_a_missing_device_port() -> None:
    with pytest.raises(ConfigError, match=r"devices\.gps\.port: required"):
        check_for_run(
            config_from_dict(
                {
                    "devices": {
                        "ahrs": {"port": "/dev/a"},
                        "pressure": {"port": "/dev/p"},
                        "motor": {"port": "/dev/m"},
                        "modem": {"port": "/dev/x"},
                    }
                }
            )
        )
    r = subprocess.run(
        [sys.executable, "-m", "navd.cli", "run", "--config", "/nonexistent.yaml"],
        capture_output=True,
        text=True,
    )
    # a config navd run cannot read is a config error: EX_CONFIG, not restarted by systemd
    assert r.returncode == 78 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
