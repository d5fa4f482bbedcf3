"""The world simulator behaves like the world it claims to be."""

from __future__ import annotations

import math

import pytest
from conftest import mission
from geographiclib.geodesic import Geodesic

from navd.hil.scenario import list_scenarios, load_scenario
from navd.hil.sim_cli import crew_config
from navd.records import Gps, Range
from navd.settings import ConfigError, config_from_dict

G = Geodesic.WGS84


@pytest.mark.parametrize("name", list_scenarios())
def test_every_scenario_loads_and_gives_a_valid_config(name: str) -> None:
    sc = load_scenario(name)
    config_from_dict(crew_config(sc))


def test_bad_scenario_key_is_named(tmp_path) -> None:
    p = tmp_path / "x.yaml"
    p.write_text("vehicle:\n  legs:\n    - heading_deg: 10\n      duration: 5\n")
    with pytest.raises(ConfigError, match=r"vehicle\.legs\[0\]\.duration: unknown key"):
        load_scenario(p)


def test_same_seed_same_mission_other_seed_other_noise() -> None:
    a, b = mission("claytor-1", 3), mission("claytor-1", 3)
    assert a.records == b.records
    c = mission("claytor-1", 4)
    assert c.records != a.records


def test_gps_only_at_the_surface_and_ranges_match_geometry() -> None:
    m = mission("claytor-1", 3)
    by_t = {round(s.t, 3): s for s in m.truth}
    for r in m.records:
        if isinstance(r, Gps) and r.fix:
            assert by_t[round(r.t, 3)].depth < 0.2
    ranges = [r for r in m.records if isinstance(r, Range) and r.beacon_lat is not None]
    assert len(ranges) >= 0.5 * m.pings
    good = 0
    for r in ranges:
        s = by_t[round(round(r.t_ping * 10) / 10, 3)]
        horiz = G.Inverse(s.lat, s.lon, s.boat_lat, s.boat_lon)["s12"]
        slant = math.hypot(horiz, 3.0 - s.depth)
        # the modem's 1500 m/s against ~1445 m/s water reads ~4 % long; GPS and rope add metres
        if abs(r.m - slant * 1500.0 / 1445.0) < 25.0:
            good += 1
    assert good >= 0.8 * len(ranges)


def test_current_moves_the_vehicle() -> None:
    m = mission("cb1", 2)
    first, last = m.truth[0], m.truth[int(50 / 0.1)]  # 50 s drifting at the surface, rpm 0
    g = G.Inverse(first.lat, first.lon, last.lat, last.lon)
    assert g["s12"] / 50.0 == pytest.approx(0.32, abs=0.06)
    assert (g["azi1"] % 360) == pytest.approx(125.0, abs=10.0)


def test_antimeridian_scenario_crosses_the_line() -> None:
    lons = [s.lon for s in mission("antimeridian", 1).truth]
    assert max(lons) > 179.99 and min(lons) < -179.99


def test_replies_to_reacquire_counts_from_the_first_rejection_to_the_next_accept() -> None:
    from navd.analysis.score import replies_to_reacquire
    from navd.schema import RangeDecision

    def r(ok: bool, reason: str = "ok") -> RangeDecision:
        return RangeDecision(0.0, 0.0, "udb", accepted=ok, reason=reason)

    ranges = [
        r(True),
        r(False, "gate"),  # a lone outlier: no re-acquisition, not counted
        r(True),
        r(False, "gate"),  # streak starts
        r(False, "corrupt_position"),  # not the gate: does not start or end a streak
        r(False, "gate"),
        r(False, "gate_reacquire"),
        r(True),  # 5 replies from the first rejection
    ]
    assert replies_to_reacquire(ranges) == [5]


def test_short_steps_follow_the_geodesic() -> None:
    """The simulator's cheap step lands where GeographicLib's Direct does, everywhere:
    the truth every benchmark is scored against rests on it."""
    from navd.hil.world import _offset

    g = Geodesic.WGS84
    for lat in (-84.0, -45.0, 0.0, 37.2, 71.0, 84.0):
        for lon in (-179.99999, -76.3, 0.0, 179.99999):
            for az in range(0, 360, 23):
                for d in (0.05, 0.15, 3.0, 40.0, 99.0, 250.0):
                    dn, de = d * math.cos(math.radians(az)), d * math.sin(math.radians(az))
                    lat2, lon2 = _offset(lat, lon, dn, de)
                    miss = g.Inverse(lat2, lon2, *_direct(g, lat, lon, az, d))["s12"]
                    assert miss < (1e-7 if d <= 10.0 else 1e-6), (lat, lon, az, d, miss)
                    assert -180.0 <= lon2 < 180.0


def _direct(g: Geodesic, lat: float, lon: float, az: float, d: float) -> tuple[float, float]:
    r = g.Direct(lat, lon, az, d)
    return r["lat2"], r["lon2"]
