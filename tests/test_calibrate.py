"""Compass deviation and speed calibration from surface runs (navd calibrate)."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest

from navd.analysis.calibrate import CalibrationError, Stretch, fit, stretches
from navd.cli import main
from navd.filter import Navigator, compass
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.records import Depth, Gps, Heading, Rpm
from navd.settings import ConfigError, config_from_dict

TRUE_DEV = [1.0, 4.0, -3.0, 1.5, -1.0]


def _runs(
    deviation: list[float], k: float = 900.0, cur: tuple[float, float] = (0.1, -0.2), n: int = 24
) -> list[Stretch]:
    """Noise-free stretches of a compass with ``deviation`` (of its own reading)."""
    out = []
    for i in range(n):
        hc = (360.0 * i / n + 7.0) % 360.0
        psi = math.radians(hc - compass.deviation_deg(deviation, hc) + 5.0)
        rpm = 1000.0
        s = rpm / k
        out.append(
            Stretch(float(i), hc, rpm, s * math.cos(psi) + cur[0], s * math.sin(psi) + cur[1])
        )
    return out


def test_the_fit_recovers_deviation_speed_and_current() -> None:
    f = fit(_runs(TRUE_DEV), declination_deg=5.0, rpm_per_mps=1000.0)
    assert f.deviation_deg == pytest.approx(TRUE_DEV, abs=1e-4)
    assert f.rpm_per_mps == pytest.approx(900.0, rel=1e-5)
    assert (f.current_n, f.current_e) == pytest.approx((0.1, -0.2), abs=1e-6)
    assert f.residual_deg < 1e-3 and f.coverage_deg > 340.0


def test_a_fit_without_headings_all_round_is_refused() -> None:
    half = [r for r in _runs(TRUE_DEV) if r.compass_deg < 200.0]
    with pytest.raises(CalibrationError, match="gap"):
        fit(half, 5.0, 1000.0)
    with pytest.raises(CalibrationError, match="too few"):
        fit(_runs(TRUE_DEV)[:3], 5.0, 1000.0)


def test_speed_calibration_with_the_deviation_known() -> None:
    f = fit(_runs(TRUE_DEV, k=820.0), 5.0, 1000.0, deviation=TRUE_DEV, fit_deviation=False)
    assert f.rpm_per_mps == pytest.approx(820.0, rel=1e-5)


def test_stretches_are_straight_steady_runs_under_way() -> None:
    recs: list[object] = []
    lat, lon = 37.0, -76.0
    for k in range(200):
        t = float(k)
        h = 90.0 if k < 100 else 180.0  # one turn at 100 s
        rpm = 900.0 if k < 180 else 0.0  # stopped for the last 20 s
        dn, de = (0.0, 1.0) if k < 100 else (-1.0, 0.0)
        if rpm == 0.0:
            dn = de = 0.0
        lat += dn / 111_000.0
        lon += de / (111_000.0 * math.cos(math.radians(37.0)))
        recs += [Heading(t, h), Rpm(t, rpm), Gps(t, lat, lon, 0.0, 1, 1.0)]
    runs = stretches(recs, window_s=60.0)
    assert [round(r.compass_deg) for r in runs] == [90, 90, 180, 180]  # 60 s at most each
    assert all(r.rpm == 900.0 for r in runs)
    assert runs[0].ve == pytest.approx(1.0, abs=0.01) and runs[-1].vn == pytest.approx(
        -1.0, abs=0.01
    )


def test_the_navigator_corrects_the_compass_by_the_configured_curve() -> None:
    cfg = config_from_dict({"navigation": {"compass_deviation_deg": TRUE_DEV}})
    nav = Navigator(cfg)
    nav.feed(Depth(0.0, 0.0))
    hc = 100.0
    nav.feed(Heading(0.0, hc))
    assert nav.inputs.heading_deg == pytest.approx(hc - compass.deviation_deg(TRUE_DEV, hc))
    with pytest.raises(ConfigError, match="compass_deviation_deg"):
        config_from_dict({"navigation": {"compass_deviation_deg": [1.0, 2.0]}})


def test_calibrate_compass_on_a_simulated_circle(tmp_path: Path, capsys) -> None:
    """The command a crew runs: a surface circle with a 6-degree curve, fitted to within
    about a degree, and a config snippet written."""
    rng = random.Random(3)
    dev = [0.5, 6.0, 0.0, -1.5, 1.0]
    circle = [{"heading_deg": (15 + 30 * i) % 360, "duration_s": 90} for i in range(12)]
    sc = {
        "name": "circle",
        "vehicle": {"lat": 37.0, "lon": -76.0, "surface_legs": circle, "legs": [{}]},
        "current": {"speed_mps": 0.2, "toward_deg": rng.uniform(0, 360)},
        "sensors": {"declination_deg": -8.0, "compass_deviation_deg": dev},
        "config": {"navigation": {"magnetic_declination_deg": -8.0}},
    }
    write_mission(simulate(scenario_from_dict(sc), 3), tmp_path)
    snippet = tmp_path / "compass.yaml"
    args = ["calibrate", "compass", str(tmp_path / "measurements.jsonl")]
    args += ["--config", str(tmp_path / "config.yaml"), "--out", str(snippet)]
    assert main(args) == 0
    fitted = config_from_dict(__import__("yaml").safe_load(snippet.read_text()))
    got = fitted.navigation.compass_deviation_deg
    for h in range(0, 360, 10):
        hc = h + compass.deviation_deg(dev, h)
        assert abs(hc - compass.deviation_deg(got, hc) - h) < 2.0, h
    assert "residual" in capsys.readouterr().out


def test_calibrate_says_in_one_line_why_not(tmp_path: Path, capsys) -> None:
    sc = {"name": "dive", "vehicle": {"lat": 37.0, "lon": -76.0, "legs": [{}]}}
    write_mission(simulate(scenario_from_dict(sc), 1), tmp_path)
    assert main(["calibrate", "compass", str(tmp_path / "measurements.jsonl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("navd: calibrate compass:")
