"""A filter state in the units an estimate is published in."""

from __future__ import annotations

import math

from navd.filter.common import StateEstimate
from navd.schema import Estimate


def fill(r: Estimate, est: StateEstimate) -> None:
    """The position (degrees), current and uncertainty (metres) of a filter state."""
    r.lat = math.degrees(est.lat)
    r.lon = math.degrees(est.lon)
    r.current_n = est.current_n
    r.current_e = est.current_e
    r.std_n = math.sqrt(max(0.0, est.var_n))
    r.std_e = math.sqrt(max(0.0, est.var_e))
    r.cov_ne = est.cov_ne
