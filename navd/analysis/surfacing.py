"""The error at surfacing of a field mission: the last submerged estimate against GPS.

What a mission without a simulator's truth has.  It uses navd's own geodesy, so the
post-mission exports need nothing beyond navd's dependencies.
"""

from __future__ import annotations

import math
from typing import Any

from navd import geodesy
from navd.records import Gps


def first_fix_after(t: float, fixes: list[Gps]) -> Gps | None:
    return next((f for f in fixes if f.t > t and f.lat is not None and f.lon is not None), None)


def surfacing_error_gps(
    estimates: list[dict[str, Any]], fixes: list[Gps]
) -> tuple[float, float] | None:
    """Distance from the last submerged estimate to the first GPS fix after it, and
    how long after it that fix came; None without both."""
    last_sub = None
    for e in estimates:
        if e["mode"] == "submerged":
            last_sub = e
    if last_sub is None:
        return None
    f = first_fix_after(last_sub["t"], fixes)
    if f is None or f.lat is None or f.lon is None:
        return None
    e_m, n_m, _ = geodesy.enu_offset(
        math.radians(f.lat),
        math.radians(f.lon),
        0.0,
        math.radians(last_sub["lat"]),
        math.radians(last_sub["lon"]),
        0.0,
    )
    return math.hypot(e_m, n_m), f.t - last_sub["t"]
