"""One bad GPS fix never moves the estimate, and integrity says when inputs disagree.

What an autopilot relies on: an estimate marked ``ok`` is near the truth.  A single
valid-checksum fix at (0, 0), or tens of kilometres off, is refused and counted; an
estimate that drifted beyond its covariance underwater is still corrected by fixes
that agree with each other; a run of refused ranges is ``degraded`` then ``lost``
however few ranges the integrity window holds.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from serialised import rows

from navd import geodesy
from navd.filter import Navigator
from navd.records import Depth, Gps, Heading, Range, Rpm
from navd.settings import config_from_dict

LAT0, LON0 = 37.05, -80.66


def _nav() -> Navigator:
    return Navigator(config_from_dict({"navigation": {"speed": {"rpm_per_mps": 1000.0}}}))


def _surface(
    nav: Navigator,
    t0: float,
    t1: float,
    lat: float = LAT0,
    lon: float = LON0,
    bad: dict[float, tuple[float, float]] | None = None,
) -> list[dict]:
    """The vehicle still at the surface, a fix a second (``bad`` replaces some)."""
    out: list[dict] = []
    t = t0
    while t < t1:
        out += nav.feed(Heading(t, 0.0))
        out += nav.feed(Depth(t + 0.01, 0.0))
        if abs(t - round(t)) < 1e-9:
            la, lo = (bad or {}).get(round(t), (lat, lon))
            out += nav.feed(Gps(t + 0.02, la, lo, 0.0, 1, 1.0, 1))
        t = round(t + 0.1, 1)
    return out


BEACON = (37.0510, -80.6600, 2.0)  # 110 m north of the start, 2 m deep


def _submerged(
    nav: Navigator, t0: float, t1: float, range_at: Callable[[float], float | None]
) -> list[dict]:
    """The vehicle at rest 5 m down, a reply from ``BEACON`` every 10 s after ``t0``
    reading ``range_at(t)`` (None: that ping was lost)."""
    out: list[dict] = []
    t = t0
    while t < t1:
        out += nav.feed(Heading(t, 0.0))
        out += nav.feed(Rpm(t + 0.01, 0.0))
        out += nav.feed(Depth(t + 0.02, 5.0))
        reply = range_at(t) if abs(t % 10.0) < 1e-6 and t > t0 else None
        if reply is not None:
            out += nav.feed(Range(t + 0.05, t - 0.5, reply, "udb", *BEACON))
        t = round(t + 0.1, 1)
    return out


def _surfaced_at_fixed_sound_speed() -> Navigator:
    """A navigator whose ranges are taken at 1500 m/s, after 20 s of fixes at the start."""
    nav = Navigator(
        config_from_dict(
            {
                "navigation": {
                    "speed": {"rpm_per_mps": 1000.0},
                    "sound_speed": {"model": "fixed", "fixed_mps": 1500.0},
                }
            }
        )
    )
    _surface(nav, 0.0, 20.0)
    return nav


def _true_range_m() -> float:
    """From the start, 5 m down, to ``BEACON``."""
    return geodesy.ecef_distance(
        math.radians(LAT0), math.radians(LON0), -5.0,
        math.radians(BEACON[0]), math.radians(BEACON[1]), -BEACON[2],
    )  # fmt: skip


def _error_m(e: dict, lat: float = LAT0, lon: float = LON0) -> float:
    de, dn, _ = geodesy.enu_offset(
        math.radians(lat),
        math.radians(lon),
        0.0,
        math.radians(e["lat"]),
        math.radians(e["lon"]),
        0.0,
    )
    return math.hypot(de, dn)


def test_one_fix_at_zero_zero_is_refused_and_moves_nothing() -> None:
    nav = _nav()
    out = _surface(nav, 0.0, 60.0, bad={40: (0.0, 0.0)})
    est = [o for o in rows(out) if o["type"] == "estimate" and o["t"] > 5.0]
    assert max(_error_m(e) for e in est) < 10.0
    assert nav.counters["gps_refused_gate"] == 1
    assert nav.counters["gps_reacquired"] == 0


def test_fixes_28_km_off_are_refused_and_said() -> None:
    """Minutes of 75 once read as 38.25 degrees: three such fixes in a row."""
    nav = _nav()
    bad = {30: (38.25, LON0), 31: (38.25, LON0), 32: (38.25, LON0)}
    out = _surface(nav, 0.0, 60.0, bad=bad)
    est = [o for o in rows(out) if o["type"] == "estimate" and o["t"] > 5.0]
    assert max(_error_m(e) for e in est) < 10.0 and nav.counters["gps_refused_gate"] == 3
    # three refused in a row: the estimate and the receiver disagree, and it is said
    assert all(o["integrity"] == "degraded" for o in est if 32.1 < o["t"] < 33.0)
    assert all(o["integrity"] == "ok" for o in est if o["t"] > 33.1)  # a good fix again


def test_fixes_that_agree_with_each_other_are_the_position() -> None:
    """The estimate drifted beyond its covariance: agreeing fixes correct it, quickly."""
    nav = _nav()
    _surface(nav, 0.0, 30.0)
    # the receiver (or the world) now says 500 m north, and keeps saying it
    north = geodesy.offset_position(math.radians(LAT0), math.radians(LON0), 500.0, 0.0, 0.0)
    lat1, lon1 = math.degrees(north[0]), math.degrees(north[1])
    out = _surface(nav, 30.0, 60.0, lat=lat1, lon=lon1)
    est = [o for o in rows(out) if o["type"] == "estimate"]
    late = [e for e in est if e["t"] > 40.0]
    assert late and max(_error_m(e, lat1, lon1) for e in late) < 10.0
    assert nav.counters["gps_reacquired"] == 1
    assert nav.counters["gps_refused_gate"] == nav.nav.gate.gps_agree - 1


def test_a_run_of_refused_ranges_is_degraded_then_lost_whatever_the_window_holds() -> None:
    nav = _nav()
    _surface(nav, 0.0, 20.0)
    # a range of 2 km from a beacon 110 m away: refused every time
    out = _submerged(nav, 20.0, 200.0, lambda t: 2000.0)
    est = [o for o in rows(out) if o["type"] == "estimate"]
    refused = [o for o in rows(out) if o["type"] == "range" and not o["accepted"]]
    assert len(refused) >= 9
    t3, t8 = refused[2]["t"], refused[7]["t"]
    assert all(e["integrity"] == "ok" for e in est if 20.5 < e["t"] < refused[1]["t"] + 0.05)
    assert all(e["integrity"] != "ok" for e in est if e["t"] > t3 + 0.2)
    # lost from the eighth on, until the ranges' own consistent evidence re-acquires (a
    # vehicle at rest cannot have drifted 2 km in minutes: it may never)
    t_re = next(
        (o["t"] for o in rows(out) if o["type"] == "range" and o["reason"] == "gate_reacquire"),
        math.inf,
    )
    assert all(e["integrity"] == "lost" for e in est if t8 + 0.2 < e["t"] < t_re)
    # a vehicle at rest is not moved to a circle 2 km off that its drift cannot reach
    assert max(_error_m(e) for e in est) < 50.0


def test_a_range_refused_as_short_is_degraded_and_one_refused_as_long_is_not() -> None:
    """Multipath only lengthens a reply: one refused as 60 m long is an outlier and the
    estimate stays ``ok``; one refused as 60 m short says the estimate is off, and it is
    ``degraded`` until a range is accepted again."""
    nav = _surfaced_at_fixed_sound_speed()
    true_m = _true_range_m()
    extra = {60: 60.0, 80: -60.0}
    out = _submerged(nav, 20.0, 110.0, lambda t: true_m + extra.get(round(t), 0.0))
    decided = {round(o["t"]): o for o in rows(out) if o["type"] == "range"}
    assert [decided[t]["accepted"] for t in range(30, 110, 10)] == [
        True, True, True, False, True, False, True, True]  # fmt: skip
    est = [o for o in rows(out) if o["type"] == "estimate"]
    assert all(e["integrity"] == "ok" for e in est if 30.2 < e["t"] < 80.0)
    short = [e for e in est if 80.2 < e["t"] < 90.0]
    assert short and all(
        e["integrity"] == "degraded" and "short" in e["integrity_reason"] for e in short
    )
    assert all(e["integrity"] == "ok" for e in est if e["t"] > 90.2)


def test_a_reply_after_a_gap_is_degraded_until_another_checks_it() -> None:
    """After two minutes without a reply the gate is wide, and the first reply accepted
    places the estimate along its line of sight almost alone.  A reflection 20 m long
    passes that gate; the estimate it placed is ``degraded`` (not ``ok``) until a next
    reply is accepted, and when the next true reply is then refused as short it stays
    so.  A reply that was true is checked by the next, and ``ok`` returns."""
    true_m = _true_range_m()
    for long_m, checked in ((20.0, False), (8.0, True)):
        nav = _surfaced_at_fixed_sound_speed()

        def reply(t: float, long_m: float = long_m) -> float | None:
            if 40.0 < t < 160.0:
                return None  # two minutes of lost pings
            return true_m + (long_m if round(t) == 160 else 0.0)

        out = _submerged(nav, 20.0, 200.0, reply)
        decided = {round(o["t"]): o for o in rows(out) if o["type"] == "range"}
        assert decided[160]["accepted"] and decided[170]["accepted"] is checked
        est = [o for o in rows(out) if o["type"] == "estimate"]
        assert all(e["integrity"] == "ok" for e in est if 150.0 < e["t"] < 160.0)
        placed = [e for e in est if 160.2 < e["t"] < 170.0]
        assert placed and all(
            e["integrity"] == "degraded" and "placed" in e["integrity_reason"] for e in placed
        )
        after = [e["integrity"] for e in est if 170.2 < e["t"] < 180.0]
        assert after and all((i == "ok") is checked for i in after)
