"""The boat's position while its location line is down: predicted, then refused."""

from __future__ import annotations

import math

from navd import geodesy
from navd.filter.beacons import BeaconResolver
from navd.hil.scenario import load_scenario, scenario_from_dict
from navd.hil.sim_cli import crew_config
from navd.hil.world import simulate
from navd.schema import RangeDecision
from navd.settings import Beacon, GateConfig

LAT0, LON0 = 38.32, -76.39


def _boat_at(t: float, vn: float = 0.3, ve: float = 0.8) -> tuple[float, float]:
    lat, lon = geodesy.offset_position(math.radians(LAT0), math.radians(LON0), vn * t, ve * t)
    return math.degrees(lat), math.degrees(lon)


def _resolver(**beacon: float) -> BeaconResolver:
    return BeaconResolver({"udb": Beacon(depth=2.0, **beacon)}, GateConfig())


def test_a_motoring_boat_is_carried_on_at_its_velocity_with_a_growing_error() -> None:
    r = _resolver(position_std_m=3.0)
    for k in range(30):  # reports every 10 s for five minutes
        fix, why = r.resolve(10.0 * k, "udb", *_boat_at(10.0 * k), 2.0)
        assert why == "ok" and fix is not None and fix.predicted_s == 0.0
    stds = []
    for age in (30.0, 120.0, 290.0):
        t = 290.0 + age
        fix, why = r.resolve(t, "udb", None, None, None)
        assert why == "ok" and fix is not None
        assert fix.predicted_s == age
        assert fix.depth == 2.0  # the configured depth, the reply having none
        lat, lon = _boat_at(t)
        e, n, _ = geodesy.enu_offset(
            fix.lat, fix.lon, 0.0, math.radians(lat), math.radians(lon), 0.0
        )
        # exact reports on a straight line: the prediction is on it
        assert math.hypot(e, n) < 0.5
        stds.append(fix.predicted_std_m)
    assert stds[0] < stds[1] < stds[2]
    # two positions 290 s apart at 3 m, for 290 s more: about 4 m from the velocity alone
    assert 4.0 < stds[2] < 40.0


def test_after_the_limit_or_without_history_the_range_is_refused() -> None:
    r = _resolver(predict_max_s=120.0)
    assert r.resolve(0.0, "udb", None, None, None) == (None, "no_beacon_position")
    for k in range(10):
        r.resolve(10.0 * k, "udb", *_boat_at(10.0 * k), 2.0)
    assert r.resolve(90.0 + 100.0, "udb", None, None, None)[1] == "ok"
    assert r.resolve(90.0 + 121.0, "udb", None, None, None) == (None, "no_beacon_position")
    # a configured limit of zero: never predicted
    r0 = _resolver(predict_max_s=0.0)
    for k in range(10):
        r0.resolve(10.0 * k, "udb", *_boat_at(10.0 * k), 2.0)
    assert r0.resolve(100.0, "udb", None, None, None) == (None, "no_beacon_position")


def test_a_jump_is_not_part_of_the_fit() -> None:
    r = _resolver()
    for k in range(10):
        r.resolve(10.0 * k, "udb", *_boat_at(10.0 * k), 2.0)
    lat, lon = _boat_at(100.0)
    assert r.resolve(100.0, "udb", lat + 0.05, lon, 2.0)[1] == "beacon_jump"
    fix, why = r.resolve(110.0, "udb", None, None, None)
    assert why == "ok" and fix is not None
    e, n, _ = geodesy.enu_offset(
        fix.lat, fix.lon, 0.0, *(math.radians(x) for x in _boat_at(110.0)), 0.0
    )
    assert math.hypot(e, n) < 0.5


def test_ranges_go_on_through_a_location_outage(tmp_path) -> None:
    """A simulated outage: its ranges are fused with the predicted boat, none refused for it."""
    from navd.filter.navigator import Navigator
    from navd.settings import config_from_dict

    base = load_scenario("claytor-2")
    data = {
        "name": "outage",
        "vehicle": {
            "lat": base.vehicle.lat,
            "lon": base.vehicle.lon,
            "depth_m": 2.0,
            "legs": [{"heading_deg": 90.0, "duration_s": 900.0}],
        },
        "boat": {"north_m": 200.0, "speed_mps": 0.5, "heading_deg": 90.0,
                 "drifts_with_current": False, "course_wander_deg_per_sqrt_s": 1.0},
        "acoustics": {"location_outages": 1, "location_outage_min_s": 200.0,
                      "location_outage_max_s": 240.0, "multipath_prob": 0.0,
                      "drop_prob": 0.0, "corrupt_position_prob": 0.0},
    }
    sc = scenario_from_dict(data)
    m = simulate(sc, 3)
    (t0, t1), = m.channel.outages
    nav = Navigator(config_from_dict(crew_config(sc)))
    decisions = []
    for rec in m.records:
        for o in nav.feed(rec):
            if isinstance(o, RangeDecision) and t0 <= o.t < t1:
                decisions.append(o)
    assert decisions, "the outage fell outside the mission"
    assert all(d.beacon_predicted_s for d in decisions)
    assert all(d.reason != "no_beacon_position" for d in decisions)
    assert sum(d.accepted for d in decisions) >= 0.8 * len(decisions)


def test_a_boat_that_wanders_is_not_predicted() -> None:
    """Holding station, turning every way: its reports fit no line, its velocity says
    nothing of where it goes next, and ranges wait for the line to return."""
    import random

    rng = random.Random(4)
    r = _resolver(position_std_m=3.0)
    n = e = 0.0
    heading = 0.0
    for k in range(30):
        heading += rng.gauss(0.0, 1.5)  # radians every 10 s: a new course each time
        n += 8.0 * math.cos(heading)
        e += 8.0 * math.sin(heading)
        lat, lon = geodesy.offset_position(math.radians(LAT0), math.radians(LON0), n, e)
        r.resolve(10.0 * k, "udb", math.degrees(lat), math.degrees(lon), 2.0)
    assert r.resolve(300.0, "udb", None, None, None) == (None, "no_beacon_position")
