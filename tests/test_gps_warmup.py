"""A receiver's first fixes are held to the warm-up floor only after it re-acquires.

What a crew relies on: the minute at the surface before a dive, with the receiver
already tracking, teaches the filter the current at the fixes' real quality; fixes
just after a re-acquisition (the receiver said it had no fix, the antenna was under
water, the fixes stopped) are still taken as poor for ``gps.warmup_s``.
"""

from __future__ import annotations

from navd.filter import Navigator
from navd.filter.gpsfix import GpsFixes
from navd.records import Depth, Gps, Heading
from navd.schema import Estimate
from navd.settings import config_from_dict

LAT0, LON0 = 37.05, -80.66
CFG = config_from_dict({})
STD = CFG.navigation.noise.gps_std_m
FLOOR = CFG.navigation.gps.warmup_std_m
WARMUP = CFG.navigation.gps.warmup_s


def _fix(t: float) -> Gps:
    return Gps(t, LAT0, LON0, 0.0, 1, 1.0, 1)


def _stds(g: GpsFixes, t0: float, t1: float) -> list[float | None]:
    return [g.judge(_fix(float(t)), True, float(t))[0] for t in range(int(t0), int(t1))]


def test_a_receiver_tracking_when_navd_starts_is_taken_at_its_stated_quality() -> None:
    g = GpsFixes(CFG.navigation, CFG.site)
    assert _stds(g, 0, 40) == [STD] * 40
    assert g.warmed_up(39.5)


def test_a_receiver_that_reports_no_fix_first_is_warming_up() -> None:
    g = GpsFixes(CFG.navigation, CFG.site)
    assert g.judge(Gps(0.0, None, None, None, 0), True, 0.0) == (None, ["gps_no_fix"])
    stds = _stds(g, 1, 1 + WARMUP + 5)
    assert stds[: int(WARMUP)] == [FLOOR] * int(WARMUP)
    assert stds[int(WARMUP) :] == [STD] * 5
    assert not g.warmed_up(1.0 + WARMUP - 0.5) and g.warmed_up(1.0 + WARMUP + 4.5)


def test_fixes_after_a_dive_are_warming_up_even_without_a_no_fix_report() -> None:
    g = GpsFixes(CFG.navigation, CFG.site)
    _stds(g, 0, 60)
    # dived at 60 s, surfaced at 600 s: the receiver sent nothing in between
    assert _stds(g, 600, 600 + WARMUP) == [FLOOR] * int(WARMUP)
    assert _stds(g, 600 + WARMUP, 600 + WARMUP + 1) == [STD]


def test_after_a_restart_the_antenna_under_water_means_a_re_acquisition() -> None:
    g = GpsFixes(CFG.navigation, CFG.site)
    _stds(g, 0, 10)
    g.forget()  # navd restarted ...
    g.antenna_under()  # ... with the vehicle submerged
    assert _stds(g, 900, 901) == [FLOOR]
    h = GpsFixes(CFG.navigation, CFG.site)
    _stds(h, 0, 10)
    h.forget()  # restarted at the surface, the receiver still tracking
    assert _stds(h, 11, 12) == [STD]


def test_the_navigator_learns_a_tracking_receivers_position_in_seconds() -> None:
    """The published std after ten seconds at the surface: the stated 3 m fixes, not the
    15 m floor (their average alone would leave about 4.7 m)."""

    def surface(first: Gps | None) -> Estimate:
        nav = Navigator(CFG)
        out: list[object] = []
        if first is not None:
            out += nav.feed(first)
        for k in range(1, 101):
            t = k * 0.1
            out += nav.feed(Heading(t, 0.0))
            out += nav.feed(Depth(t + 0.01, 0.0))
            if k % 10 == 0:
                out += nav.feed(_fix(t + 0.02))
        out += nav.advance(10.5)
        est = [o for o in out if isinstance(o, Estimate)]
        assert est
        return est[-1]

    tracking = surface(None)
    acquiring = surface(Gps(0.0, None, None, None, 0))
    assert tracking.std_n < 2.0 and tracking.mode == "surface"
    assert acquiring.std_n > 4.0 and acquiring.mode == "surfacing"
