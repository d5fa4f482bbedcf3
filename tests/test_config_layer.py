"""One config layer: site overlays, check-config judging as navd run does, EX_CONFIG,
and the systemd defaults for the config and log paths."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from navd.config import default_config_path, load_config, log_dir
from navd.settings import ConfigError, config_from_dict

ROOT = Path(__file__).resolve().parent.parent


def _navd(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "navd", *args], capture_output=True, text=True, timeout=60, env=env
    )


def test_a_site_overlay_wins_over_the_vehicle_file(tmp_path: Path) -> None:
    (tmp_path / "site.yaml").write_text(
        "navigation:\n  magnetic_declination_deg: -11.0\nsite:\n  name: chesapeake\n"
    )
    (tmp_path / "navd.yaml").write_text(
        "overlays: [site.yaml]\nnavigation:\n  magnetic_declination_deg: -8.1\n  rate_hz: 5\n"
    )
    cfg = load_config(tmp_path / "navd.yaml")
    assert cfg.navigation.magnetic_declination_deg == -11.0  # the site's
    assert cfg.navigation.rate_hz == 5  # the vehicle's, untouched by the site
    assert cfg.site.name == "chesapeake"


def test_the_shipped_site_files_apply_on_the_shipped_config() -> None:
    base = load_config(ROOT / "config" / "navd.yaml")
    bay = load_config(
        ROOT / "config" / "navd.yaml", [ROOT / "config" / "sites" / "chesapeake-bay.yaml"]
    )
    assert bay.site.name != base.site.name
    assert bay.devices == base.devices  # a site changes the water, not the vehicle


def test_an_overlay_loop_is_one_error_naming_it(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text("overlays: b.yaml\n")
    (tmp_path / "b.yaml").write_text("overlays: a.yaml\n")
    with pytest.raises(ConfigError, match="overlays nested deeper"):
        load_config(tmp_path / "a.yaml")


def test_an_error_in_an_overlay_names_the_key(tmp_path: Path) -> None:
    (tmp_path / "site.yaml").write_text("navigation:\n  rate_hz: fast\n")
    (tmp_path / "navd.yaml").write_text("overlays: [site.yaml]\n")
    with pytest.raises(ConfigError, match="navigation.rate_hz"):
        load_config(tmp_path / "navd.yaml")
    (tmp_path / "navd.yaml").write_text("overlays: [missing.yaml]\n")
    with pytest.raises(ConfigError, match="missing.yaml"):
        load_config(tmp_path / "navd.yaml")


def test_site_option_on_the_command_line(tmp_path: Path) -> None:
    site = ROOT / "config" / "sites" / "chesapeake-bay.yaml"
    r = _navd("check-config", str(ROOT / "config" / "navd.yaml"), "--site", str(site))
    assert r.returncode == 0, r.stderr
    assert "chesapeake-bay.yaml: ok" in r.stdout


def test_check_config_shows_the_merged_result_as_a_config(tmp_path: Path) -> None:
    site = ROOT / "config" / "sites" / "chesapeake-bay.yaml"
    r = _navd("check-config", str(ROOT / "config" / "navd.yaml"), "--site", str(site), "--merged")
    assert r.returncode == 0, r.stderr
    merged = yaml.safe_load(r.stdout)
    # the site's values won, the defaults are there, and it is a config navd reads as is
    assert merged["navigation"]["speed"]["rpm_per_mps"] == 1150
    assert merged["navigation"]["gate"]["chi2"] == 9.0
    assert config_from_dict(merged) == load_config(ROOT / "config" / "navd.yaml", [site])


def test_check_config_refuses_what_run_refuses(tmp_path: Path) -> None:
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    r = _navd("check-config", str(empty))
    assert r.returncode == 2
    assert "devices.ahrs.port" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = _navd("check-config", str(empty), "--offline")  # a config only for replay
    assert r.returncode == 0, r.stderr


def test_run_exits_78_on_a_config_error(tmp_path: Path) -> None:
    bad = tmp_path / "navd.yaml"
    bad.write_text("navigation:\n  rate_hz: 0\n")
    r = _navd("run", "--config", str(bad))
    assert r.returncode == 78
    assert "navigation.rate_hz" in r.stderr and "Traceback" not in r.stderr
    # without --config and outside systemd there is nothing to run
    env = {k: v for k, v in os.environ.items() if k != "CONFIGURATION_DIRECTORY"}
    r = _navd("run", env=env)
    assert r.returncode == 78 and "--config" in r.stderr


def test_systemd_directories_are_the_defaults() -> None:
    cfg = load_config(None)
    assert default_config_path({"CONFIGURATION_DIRECTORY": "/etc/navd"}) == "/etc/navd/navd.yaml"
    assert default_config_path({}) is None
    assert log_dir(cfg, {"LOGS_DIRECTORY": "/var/log/navd"}) == "/var/log/navd"
    assert log_dir(cfg, {}) == "navd-log"  # a development run
    named = load_config(None).__class__(log=cfg.log.__class__(dir="/data/navd"))
    assert log_dir(named, {"LOGS_DIRECTORY": "/var/log/navd"}) == "/data/navd"


def test_report_reads_the_decisions_of_a_daemon_log(tmp_path: Path) -> None:
    """The daemon's log writes a range decision as ``decision`` (its ranges are
    measurements there): the report still counts them."""
    from navd.formats.log import RecordLog
    from navd.records import Range
    from navd.schema import Estimate, RangeDecision, from_dict

    rlog = RecordLog(tmp_path / "log")
    est = {"type": "estimate", "t": 10.0, "lat": 37.0, "lon": -80.6, "current_n": 0.0}
    est |= {"current_e": 0.0, "std_n": 3.0, "std_e": 3.0, "cov_ne": 0.0, "depth": 2.0}
    est |= {"mode": "submerged", "integrity": "ok", "heading_deg": 0.0, "speed_mps": 1.0}
    rlog.record(Range(10.0, 9.0, 700.0, "udb", 37.006, -80.6, 3.0))
    rlog.output(from_dict(Estimate, est))
    rlog.output(
        RangeDecision(
            10.0, 9.0, "udb", accepted=True, residual_m=1.0, gate_m=9.0, reason="ok", range_m=700.0
        )
    )
    rlog.output(from_dict(Estimate, {**est, "t": 10.1}))
    rlog.close()
    assert rlog.path is not None
    r = _navd("report", str(rlog.path), "--out", str(tmp_path / "rep"))
    assert r.returncode == 0, r.stderr
    assert "ranges: 1 reached the filter, 1 accepted" in r.stdout


def test_report_of_a_wrong_file_is_one_line(tmp_path: Path) -> None:
    for text in ("not json\n", '{"type": "estimate", "t": 1}\n', '{"format": "x"}\n'):
        f = tmp_path / "wrong.jsonl"
        f.write_text(text)
        r = _navd("report", str(f), "--out", str(tmp_path / "rep"))
        assert r.returncode == 2
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_check_config_says_the_tidal_prediction_it_will_follow(tmp_path: Path) -> None:
    day = tmp_path / "day.yaml"
    day.write_text(
        "navigation:\n  filter: thesis\n  tide: {amplitude_mps: 0.5, toward_deg: 10, "
        'max_flood_utc: "2016-04-14T15:20:00Z"}\n'
    )
    r = _navd("check-config", str(ROOT / "config" / "navd.yaml"), "--site", str(day))
    assert r.returncode == 0, r.stderr
    assert "tidal prediction: 0.5 m/s toward 10 deg" in r.stdout
    assert "the thesis mode does not use the tidal prediction" in r.stdout
    day.write_text("navigation:\n  tide: {amplitude_mps: 0.5}\n")
    r = _navd("check-config", str(ROOT / "config" / "navd.yaml"), "--site", str(day))
    assert r.returncode != 0
    assert "navigation.tide.max_flood_utc" in r.stderr and "Traceback" not in r.stderr
