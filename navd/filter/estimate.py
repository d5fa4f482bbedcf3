"""An estimate as it is published: a filter state and what stands beside it, in the
units of docs/schema.md (degrees, metres, m/s), built once and never changed."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

from navd import geodesy
from navd.filter.common import Corrections, StateEstimate
from navd.filter.deadreckoning import DeadReckoner
from navd.filter.dvl import DvlDeadReckoner
from navd.filter.vlbl import VirtualNet
from navd.schema import Estimate

FIX_MAX_AGE_S = 30.0  # an acoustic fix older than this is not published


class Placed(NamedTuple):
    """The position (degrees), current and uncertainty (metres) of a filter state."""

    lat: float
    lon: float
    current_n: float
    current_e: float
    std_n: float
    std_e: float
    cov_ne: float


def placed(est: StateEstimate) -> Placed:
    return Placed(
        math.degrees(est.lat),
        math.degrees(est.lon),
        est.current_n,
        est.current_e,
        math.sqrt(max(0.0, est.var_n)),
        math.sqrt(max(0.0, est.var_e)),
        est.cov_ne,
    )


def smoothed(filtered: Estimate, est: StateEstimate) -> Estimate:
    """A tick's estimate with the smoother's state in place of the filter's."""
    p = placed(est)
    return replace(
        filtered,
        smoothed=True,
        lat=p.lat,
        lon=p.lon,
        current_n=p.current_n,
        current_e=p.current_e,
        std_n=p.std_n,
        std_e=p.std_e,
        cov_ne=p.cov_ne,
    )


def build(
    t: float,
    state: StateEstimate,
    *,
    depth: float,
    mode: str,
    integrity: str,
    integrity_reason: str | None,
    corrections: Corrections | None,
    heading: float,
    speed: float,
    dr: DeadReckoner,
    net: VirtualNet,
    dvl: DvlDeadReckoner | None,
    stale: list[str] | None,
) -> Estimate:
    """One tick's estimate.  ``heading`` (radians, true) and ``speed`` are the inputs as
    measured; the mode's corrections, if it has any, are applied here."""
    c = corrections
    if c is not None:
        heading += c.heading_bias
        speed *= c.speed_scale
    fx = net.fix
    fix_age = None if fx is None or net.t_fix is None else t - net.t_fix
    if fix_age is not None and fix_age > FIX_MAX_AGE_S:
        fx = fix_age = None
    dr_on = dr.lat is not None and dr.lon is not None
    if dvl is not None and (dvl.lat is None or dvl.lon is None):
        dvl = None
    p = placed(state)
    return Estimate(
        t=round(t, 9),
        lat=p.lat,
        lon=p.lon,
        current_n=p.current_n,
        current_e=p.current_e,
        std_n=p.std_n,
        std_e=p.std_e,
        cov_ne=p.cov_ne,
        depth=depth,
        mode=mode,
        integrity=integrity,
        integrity_reason=integrity_reason or None,
        heading_bias_deg=None if c is None else math.degrees(c.heading_bias),
        speed_scale=None if c is None else c.speed_scale,
        beacon_offset_n=None if c is None else c.beacon_offset_n,
        beacon_offset_e=None if c is None else c.beacon_offset_e,
        calibration_doubt=None if c is None else c.calibration_doubt,
        calibration_refuted=None if c is None else c.calibration_refuted,
        heading_deg=math.degrees(geodesy.wrap_lon(heading)) % 360.0,
        speed_mps=speed,
        dr_lat=_deg(dr.lat) if dr_on else None,
        dr_lon=_deg(dr.lon) if dr_on else None,
        fix_lat=None if fx is None else math.degrees(fx.lat),
        fix_lon=None if fx is None else math.degrees(fx.lon),
        fix_std_m=None if fx is None else math.sqrt(0.5 * float(fx.cov_ne[0, 0] + fx.cov_ne[1, 1])),
        fix_age_s=fix_age,
        dvl_lat=None if dvl is None else _deg(dvl.lat),
        dvl_lon=None if dvl is None else _deg(dvl.lon),
        dvl_error_pred_m=None if dvl is None else dvl.pred_error_m,
        dvl_time_to_limit_s=None if dvl is None else dvl.time_to_limit_s(),
        stale=stale or None,
    )


def _deg(rad: float | None) -> float | None:
    return None if rad is None else math.degrees(rad)
