"""Virtual LBL (seed 001) and the acoustic fix: beside the filter, and to start it without GPS."""

from __future__ import annotations

import pytest
from conftest import mission

from navd import geodesy
from navd.analysis.replay import run_navigator
from navd.analysis.score import score
from navd.filter.vlbl import NetRange, VirtualNet
from navd.formats.mlog import MeasurementLog
from navd.hil.sim_cli import mission_config
from navd.records import Gps
from navd.settings import ConfigError, config_from_dict, deep_merge


def _run(name: str, records=None):
    m = mission(name, 1)
    cfg = config_from_dict(mission_config(m))
    res = run_navigator(MeasurementLog({}, records or m.records, []), cfg)
    return res, score(res.outputs, m.truth)


def test_virtual_net_from_one_beacon_in_time() -> None:
    """A vehicle running past one fixed beacon: three ranges in time make a fix."""
    lat0, lon0 = 0.8, -1.3
    blat, blon = geodesy.offset_position(lat0, lon0, 300.0, 0.0)
    net = VirtualNet(drift_mps=0.0)
    fix = None
    for k in range(4):  # eastward at 1.5 m/s, a range every 20 s
        e = 30.0 * k
        plat, plon = geodesy.offset_position(lat0, lon0, 0.0, e)
        r = geodesy.ecef_distance(plat, plon, 0.0, blat, blon, 0.0)
        fix = net.add(
            NetRange(20.0 * k, blat, blon, 0.0, r, 1.0, 0.0, e),
            0.0,
            geodesy.offset_position(lat0, lon0, -20.0, 60.0),
        )
    assert fix is not None
    plat, plon = geodesy.offset_position(lat0, lon0, 0.0, 90.0)
    de, dn, _ = geodesy.enu_offset(plat, plon, 0.0, fix.lat, fix.lon, 0.0)
    assert abs(de) < 0.01 and abs(dn) < 0.01


def test_lbl_fix_published_beside_the_filter() -> None:
    _, s = _run("lbl-3")
    assert s.fix_coverage > 0.9 and s.fix_rms_m < 8.0
    assert s.rms_m < s.fix_rms_m  # the filter, with the dynamics, beats the static fix


def test_single_beacon_vlbl_compared() -> None:
    _, s = _run("survey")
    assert s.fix_coverage > 0.5 and s.fix_rms_m < 60.0


def test_acoustic_fix_initialises_without_gps() -> None:
    m = mission("lbl-3", 1)
    no_gps = [r for r in m.records if not isinstance(r, Gps)]
    res, s = _run("lbl-3", no_gps)
    assert res.counters["initialised_from_acoustic_fix"] == 1
    assert s.rms_m < 10.0


def test_vlbl_selectable_as_the_navigation_mode() -> None:
    m = mission("lbl-3", 1)
    cfg = config_from_dict(
        deep_merge(
            mission_config(m),
            {"navigation": {"filter": "vlbl"}},
        )
    )
    res = run_navigator(MeasurementLog({}, m.records, []), cfg)
    s = score(res.outputs, m.truth)
    assert s.rms_m < 8.0 and s.dr_rms_m > 3 * s.rms_m
    with pytest.raises(ConfigError, match="smooth"):
        run_navigator(MeasurementLog({}, m.records, []), cfg, smooth=True)
