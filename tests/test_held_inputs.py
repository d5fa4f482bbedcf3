"""Inputs that change between ticks: the filter steps once a tick with the mean of what
was held, and moves the vehicle as far as the held values did."""

from __future__ import annotations

import math

from navd.filter import Navigator
from navd.filter.inputs import HeldInputs
from navd.geodesy import nearby_offset
from navd.records import Attitude, Gps, Heading, Rpm
from navd.settings import config_from_dict

LAT0, LON0 = 37.05, -80.66


def _nav() -> Navigator:
    # no declination, an RPM map of 100 RPM per m/s and no offset: speeds are exact
    return Navigator(
        config_from_dict(
            {
                "navigation": {
                    "magnetic_declination_deg": 0.0,
                    "speed": {"rpm_per_mps": 100.0, "offset_mps": 0.0},
                }
            }
        )
    )


def test_a_turn_inside_a_step_moves_by_the_mean_velocity() -> None:
    nav = _nav()
    held = HeldInputs(nav.nav)
    held.heading(Heading(0.0, 0.0))
    held.motor(Rpm(0.0, 100.0))  # 1 m/s
    held.carry(0.0, 0.05)
    held.heading(Heading(0.05, 90.0))
    heading, speed = held.over(0.0, 0.1)
    # 5 cm north, then 5 cm east: 7.07 cm to the north-east in 0.1 s
    assert math.isclose(math.degrees(heading), 45.0, abs_tol=1e-9)
    assert math.isclose(speed, math.sqrt(2.0) / 2.0, rel_tol=1e-12)


def test_a_step_with_one_held_value_uses_it_unchanged() -> None:
    nav = _nav()
    held = HeldInputs(nav.nav)
    held.heading(Heading(0.0, 33.3))
    held.motor(Rpm(0.0, 150.0))
    held.carry(0.0, 0.04)  # a record that changes nothing
    assert held.over(0.0, 0.1) == held.heading_speed()
    assert held.over(0.1, 0.2) == held.heading_speed()  # nothing carried for this step


def _fly(records_per_tick: int, seconds: float) -> tuple[Navigator, int]:
    """A vehicle turning at 9 degrees a second at 1.5 m/s, its AHRS sampled
    ``records_per_tick`` times a tick off the tick grid; how many filter steps it took."""
    nav = _nav()
    steps = 0
    predict = nav.filter.predict

    def counting(*a: float) -> None:
        nonlocal steps
        steps += 1
        predict(*a)

    nav.feed(Gps(0.0, LAT0, LON0, 0.0, 1, 1.0))
    nav.filter.predict = counting  # type: ignore[method-assign]
    n = int(seconds * 10 * records_per_tick)
    for k in range(1, n + 1):
        t = k * 0.1 / records_per_tick + 0.013
        if t > seconds:
            break
        nav.feed(Attitude(t, 0.0, 0.0, (9.0 * t) % 360.0))
        nav.feed(Rpm(t, 150.0))
    nav.advance(seconds)
    return nav, steps


def test_the_filter_steps_once_a_tick_however_often_the_inputs_change() -> None:
    # two filters in the default mode's bank, one step each a tick
    _, steps = _fly(records_per_tick=4, seconds=20.0)
    _, steps_slow = _fly(records_per_tick=1, seconds=20.0)
    assert steps == steps_slow
    assert steps <= 2 * 20 * 10 + 2


def test_the_track_matches_the_held_inputs_to_a_millimetre() -> None:
    # a circle of 20 s flown with the AHRS at 20 Hz: the mean-velocity step must land
    # where stepping at every sample lands (the held values' exact sum)
    nav, _ = _fly(records_per_tick=2, seconds=20.0)
    n, e = 0.0, 0.0
    t_prev, heading = 0.0, None
    for k in range(1, 401):
        t = k * 0.05 + 0.013
        if t > 20.0:
            break
        if heading is not None:
            n += 1.5 * math.cos(heading) * (t - t_prev)
            e += 1.5 * math.sin(heading) * (t - t_prev)
        t_prev, heading = t, math.radians((9.0 * t) % 360.0)
    assert heading is not None
    n += 1.5 * math.cos(heading) * (20.0 - t_prev)
    e += 1.5 * math.sin(heading) * (20.0 - t_prev)
    assert nav.dr.lat is not None and nav.dr.lon is not None
    lat, lon = nav.dr.lat, nav.dr.lon
    dn, de = nearby_offset(math.radians(LAT0), math.radians(LON0), lat, lon)
    assert math.hypot(dn - n, de - e) < 1e-3
