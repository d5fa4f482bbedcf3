"""The navigation core is total: no finite input makes the navigator raise or emit a NaN.

Records are built directly (not through the log reader, which refuses much of this
already), around a vehicle near fixed transponders whose geometry is as bad as it
gets: coincident, collinear, on top of the vehicle, the vehicle on their baseline.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from serialised import rows

from navd.filter import Navigator
from navd.records import (
    Attitude,
    Clock,
    Depth,
    Gps,
    Heading,
    Pressure,
    Range,
    Reset,
    Resume,
    Rpm,
    SetBeacon,
    TravelTime,
    Velocity,
)
from navd.schema import Estimate, Published
from navd.settings import config_from_dict

LAT0, LON0 = 37.05, -80.66
D = 1e-4  # about 11 m of latitude
# three transponders on one line through the start, two of them in the same place
BEACONS = {
    "a": {"lat": LAT0, "lon": LON0 - 5 * D, "depth": 5.0},
    "b": {"lat": LAT0, "lon": LON0 + 5 * D, "depth": 5.0},
    "c": {"lat": LAT0, "lon": LON0 + 5 * D, "depth": 5.0},
}

finite = st.floats(allow_nan=False, allow_infinity=False)
near = st.one_of(st.floats(-20 * D, 20 * D), st.sampled_from([0.0, 5 * D, -5 * D]))
small = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([0.0, -0.0, 1e-300, -1.0]), finite)
dt = st.one_of(st.floats(0.0, 2.0), st.sampled_from([0.0, 1e-9, 0.1, 30.0]), st.floats(-3.0, 0.0))
beacon_name = st.sampled_from(["a", "b", "c", "udb", "new"])
opt_pos = st.one_of(st.none(), near)


@st.composite
def record(draw: st.DrawFn, t: float) -> object:
    kind = draw(st.integers(0, 13))
    if kind == 0:
        return Heading(t, draw(small))
    if kind == 1:
        return Attitude(t, draw(small), draw(small), draw(small))
    if kind == 2:
        return Rpm(t, draw(small))
    if kind == 3:
        return Depth(t, draw(st.one_of(st.floats(-1.0, 50.0), small)))
    if kind == 4:
        return Pressure(t, draw(st.one_of(st.floats(0.9, 5.0), small)))
    if kind == 5:
        return Gps(
            t,
            LAT0 + draw(near),
            LON0 + draw(near),
            draw(st.one_of(st.none(), small)),
            draw(st.sampled_from([0, 1, 2])),
            draw(st.one_of(st.none(), small)),
        )
    if kind in (6, 7):
        lat, lon = draw(opt_pos), draw(opt_pos)
        return Range(
            t,
            t - draw(st.one_of(st.floats(0.0, 20.0), small)),
            draw(st.one_of(st.floats(-5.0, 500.0), st.sampled_from([0.0, 5.0, 1e-9]), small)),
            draw(beacon_name),
            None if lat is None else LAT0 + lat,
            None if lon is None else LON0 + lon,
            draw(st.one_of(st.none(), st.floats(-5.0, 50.0))),
        )
    if kind == 8:
        return TravelTime(
            t, t - draw(st.floats(0.0, 20.0)), draw(small), draw(beacon_name), None, None, None
        )
    if kind == 9:
        return Velocity(t, draw(small), draw(small), draw(small))
    if kind == 10:
        return SetBeacon(t, draw(beacon_name), LAT0 + draw(near), LON0 + draw(near), 0.0)
    if kind == 11:
        # a restart's checkpoint: any mode, any shape, any covariance (negative, singular)
        n = draw(st.sampled_from([2, 4, 8, 3]))
        x = [math.radians(LAT0) + draw(near), math.radians(LON0) + draw(near)]
        x += [draw(small) for _ in range(n - 2)]
        P = [draw(small) for _ in range(draw(st.sampled_from([n * n, n, 4])))]
        mode = draw(st.sampled_from(["default", "thesis", "vlbl"]))
        return Resume(
            t,
            mode,
            tuple(x),
            tuple(P),
            draw(st.floats(0.0, 1e4)),
            None,
            None,
            draw(st.one_of(st.none(), st.floats(-1.0, 50.0))),
        )
    if kind == 12:
        # the receiver's UTC: hours off the computer's, a rollover's 2007, nonsense
        return Clock(t, 1460647200.0 + draw(st.one_of(small, st.floats(-1e9, 1e9))))
    return Reset(t)


@st.composite
def streams(draw: st.DrawFn) -> list[object]:
    t = 0.0
    # start at the surface with GPS, so the filter is initialised for most examples
    out: list[object] = [Gps(0.1 * k, LAT0, LON0, 0.0, 1) for k in range(draw(st.integers(0, 5)))]
    for _ in range(draw(st.integers(1, 60))):
        t += draw(dt)
        out.append(draw(record(t)))
    return out


def _check(out: Iterable[Published]) -> None:
    for o in rows(out):
        for k, v in o.items():
            if isinstance(v, float):
                assert math.isfinite(v), (k, o)


@given(st.sampled_from(["default", "thesis", "vlbl"]), streams())
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_no_finite_record_stream_makes_the_navigator_raise(mode: str, recs: list) -> None:
    # with a strong, fast tidal prediction, so that its path is under test too
    tide = {"amplitude_mps": 3.0, "period_s": 3600.0, "max_flood_utc": "2016-04-14T15:20:00Z"}
    cfg = config_from_dict({"navigation": {"filter": mode, "tide": tide}, "beacons": BEACONS})
    nav = Navigator(cfg, keep_history=mode != "vlbl")
    nav.set_clock(1460647200.0)
    out: list[Published] = []
    for r in recs:
        out += nav.feed(r)
    out += nav.advance(recs[-1].t + 1.0)
    heading = next((o.heading_deg for o in reversed(out) if isinstance(o, Estimate)), None)
    out.append(nav.advisory(recs[-1].t + 1.0, heading))  # the daemon's 1 Hz advisory too
    _check(out)
    if mode != "vlbl":
        _check(nav.smoothed())


def test_the_vehicle_on_the_baseline_of_two_transponders() -> None:
    """Two fixed transponders, the vehicle running along the line through them."""
    two = {k: BEACONS[k] for k in ("a", "b")}
    for mode in ("default", "thesis", "vlbl"):
        nav = Navigator(config_from_dict({"navigation": {"filter": mode}, "beacons": two}))
        out: list[dict] = []
        for k in range(20):
            out += nav.feed(Gps(k * 0.1, LAT0, LON0, 0.0, 1))
        out += nav.feed(Depth(2.05, 3.0))
        for k in range(40):
            t = 3.0 + 2.0 * k
            out += nav.feed(Heading(t - 0.5, 90.0))
            out += nav.feed(Rpm(t - 0.4, 910.0))
            name = "ab"[k % 2]
            out += nav.feed(Range(t, t - 0.1, 44.0 + (k % 3), name))
        _check(out)
        assert nav.counters["ranges_accepted"] + nav.counters["ranges_rejected"] == 40


@given(
    st.lists(st.floats(-500.0, 500.0), min_size=3, max_size=6),
    st.sampled_from([0.0, 1e-12, 1e-7, 1e-3]),
    st.lists(st.floats(-10.0, 600.0), min_size=6, max_size=6),
    st.sampled_from([1e-3, 3.0, 1e3]),
)
@settings(max_examples=300, deadline=None)
def test_a_fix_from_collinear_beacons_is_none_or_finite(
    east: list[float], wobble: float, ranges: list[float], std: float
) -> None:
    """Beacons on one line (the seed-003 two-transponder case): no fix, never an error."""
    from navd import geodesy
    from navd.filter.lsfix import RangeTo, least_squares_fix

    lat0, lon0 = math.radians(LAT0), math.radians(LON0)
    rs = []
    for i, e in enumerate(east):
        la, lo = geodesy.offset_position(lat0, lon0, wobble * (i % 2), e, -5.0)
        rs.append(RangeTo(la, lo, -5.0, ranges[i], std))
    fix = least_squares_fix(rs, -3.0, (lat0, lon0))
    if fix is not None:
        assert math.isfinite(fix.lat) and math.isfinite(fix.lon)
        assert float(fix.cov_ne[0, 0]) > 0.0 and float(fix.cov_ne[1, 1]) > 0.0
