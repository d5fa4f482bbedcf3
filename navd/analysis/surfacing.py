"""The error at surfacing of a field mission: the last submerged estimate against GPS.

What a mission without a simulator's truth has.  It uses navd's own geodesy, so the
post-mission exports need nothing beyond navd's dependencies.
"""

from __future__ import annotations

import math

from navd import geodesy
from navd.formats.mission import Surfacing
from navd.records import Gps
from navd.schema import Estimate


def first_fix_after(t: float, fixes: list[Gps]) -> Gps | None:
    return next((f for f in fixes if f.t > t and f.lat is not None and f.lon is not None), None)


def surfacing_error_gps(
    estimates: list[Estimate], fixes: list[Gps]
) -> tuple[float, float] | None:
    """Distance from the last submerged estimate to the first GPS fix after it, and
    how long after it that fix came; None without both."""
    last_sub = None
    for e in estimates:
        if e.mode == "submerged":
            last_sub = e
    if last_sub is None:
        return None
    found = _surfacing(last_sub, fixes)
    return None if found is None else (found.error_m, found.after_s)


def _surfacing(last: Estimate, fixes: list[Gps]) -> Surfacing | None:
    f = first_fix_after(last.t, fixes)
    if f is None or f.lat is None or f.lon is None:
        return None
    e_m, n_m, _ = geodesy.enu_offset(
        math.radians(f.lat),
        math.radians(f.lon),
        0.0,
        math.radians(last.lat),
        math.radians(last.lon),
        0.0,
    )
    return Surfacing(last.t, last.lat, last.lon, f.lat, f.lon, math.hypot(e_m, n_m), f.t - last.t)


def surfacings(estimates: list[Estimate], fixes: list[Gps]) -> list[Surfacing]:
    """One per dive: where the vehicle thought it was when it came up, and GPS."""
    out = []
    dive: Estimate | None = None  # the last submerged estimate of the dive under way
    for e in estimates:
        if e.mode == "submerged":
            dive = e
        elif dive is not None:
            s = _surfacing(dive, fixes)
            if s is not None:
                out.append(s)
            dive = None
    if dive is not None:
        s = _surfacing(dive, fixes)
        if s is not None:
            out.append(s)
    return out
