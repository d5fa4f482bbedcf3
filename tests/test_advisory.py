"""The observability advisory: it fires on a radial track, not on a crossing one, and
suggests steering across the line of sight with the smaller turn."""

from __future__ import annotations

import math

import pytest

from navd import geodesy
from navd.filter.advisory import Observability

BEACON = (37.05, -80.66)


def _at(north_m: float, east_m: float) -> tuple[float, float]:
    lat, lon = geodesy.offset_position(
        math.radians(BEACON[0]), math.radians(BEACON[1]), north_m, east_m, 0.0
    )
    return math.degrees(lat), math.degrees(lon)


def _feed(track: list[tuple[float, float]]) -> Observability:
    obs = Observability()
    for k, (n, e) in enumerate(track):
        obs.add(10.0 * k, *_at(n, e), *BEACON, 3.0)
    return obs


def test_a_radial_run_is_weak_across_the_line_of_sight() -> None:
    # running north, away from the beacon: every line of sight points south
    obs = _feed([(100.0 + 15.0 * k, 0.0) for k in range(20)])
    a = obs.assess(190.0, heading_deg=0.0)
    assert a.verdict == "weak_cross_range"
    assert a.weak_axis_deg == pytest.approx(90.0, abs=1.0)  # east-west is unobserved
    assert abs(a.suggest_turn_deg or 0.0) == pytest.approx(90.0, abs=1.0)
    assert a.suggest_heading_deg in (pytest.approx(90.0, abs=1), pytest.approx(270.0, abs=1))


def test_a_crossing_run_is_ok_and_gives_no_advice() -> None:
    # passing the beacon 100 m abeam: the bearings sweep through 140 degrees
    obs = _feed([(-300.0 + 30.0 * k, 100.0) for k in range(20)])
    a = obs.assess(190.0, heading_deg=0.0)
    assert a.verdict == "ok" and a.suggest_heading_deg is None
    assert (a.bearing_spread_deg or 0.0) > 90.0


def test_the_smaller_turn_is_suggested() -> None:
    obs = _feed([(100.0 + 15.0 * k, 0.0) for k in range(20)])
    a = obs.assess(190.0, heading_deg=60.0)  # already turning east
    assert a.suggest_heading_deg == pytest.approx(90.0, abs=1.0)
    assert a.suggest_turn_deg == pytest.approx(30.0, abs=1.0)


def test_old_ranges_leave_the_window_and_none_is_said() -> None:
    obs = _feed([(100.0 + 15.0 * k, 0.0) for k in range(5)])
    assert obs.assess(40.0, 0.0).ranges == 5
    a = obs.assess(40.0 + 400.0, 0.0)
    assert a.verdict == "no_ranges" and a.ranges == 0


def test_above_the_beacon_adds_nothing_and_never_raises() -> None:
    obs = Observability()
    obs.add(0.0, *BEACON, *BEACON, 3.0)
    obs.add(1.0, *_at(10.0, 0.0), *BEACON, 0.0)
    assert obs.assess(2.0, math.nan).verdict == "no_ranges"


def test_watch_reprints_advice_only_when_it_changes() -> None:
    from navd.schema import Advisory
    from navd.watch import advice_changed

    def weak(heading: float, axis: float = 40.0) -> Advisory:
        return Advisory(0.0, "weak_cross_range", 6, 300.0, 10.0, 0.1, axis, 30.0, heading, 5.0)

    first = weak(120.0)
    assert advice_changed(None, first)
    # a degree or two of wander from second to second: the same advice
    assert not advice_changed(first, weak(121.5))
    assert not advice_changed(first, weak(118.0, axis=42.0))
    # across north the wander is still small
    assert not advice_changed(weak(359.0), weak(3.0))
    # a turn that moved by ten degrees, another weak axis, or another verdict is news
    assert advice_changed(first, weak(131.0))
    assert advice_changed(first, weak(120.0, axis=60.0))
    assert advice_changed(first, Advisory(0.0, "ok", 9, 300.0, 80.0))
