"""``navd calibrate compass|speed LOG``: the compass deviation curve and the RPM map, from
surface runs with GPS.

At the surface GPS gives the velocity over ground.  Over a straight stretch of
``window_s`` it is modelled as the water speed along the true heading plus the
current:

    v_ground = (rpm / rpm_per_mps + offset) * (cos psi, sin psi) + current
    psi = compass - deviation(compass) + declination

``deviation`` is the five-term curve of navd/filter/compass.py.  A Gauss-Newton fit
over every stretch gives the unknowns with their covariance: the deviation, the
speed scale and the current (``compass``), or the speed scale, an offset when the
runs were at several RPMs, and the current (``speed``, deviation as configured).
Fitting the current with them is what lets a circle in a tidal stream calibrate;
it needs headings all round, so a fit whose headings leave a gap over 90 degrees is
refused, in one line.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from navd import geodesy
from navd.filter import compass
from navd.records import Attitude, Gps, Heading, Rpm

#: the widest heading gap a deviation fit accepts (its harmonics need headings all round)
MAX_GAP_DEG = 90.0
_MIN_SPEED_MPS = 0.3  # slower, the heading of the ground track is noise
_MAX_TURN_DEG = 5.0  # a compass this far from the stretch's first reading is a turn
_MIN_FIXES = 15  # a shorter stretch's velocity is mostly GPS noise
_MAX_HDOP = 2.0  # fixes just after surfacing (poor) are left out


class CalibrationError(Exception):
    """Why the log cannot be calibrated from (one line)."""


@dataclass(frozen=True, slots=True)
class Stretch:
    """A straight run at the surface: the compass, the RPM and the GPS velocity over it."""

    t: float
    compass_deg: float
    rpm: float
    vn: float
    ve: float


def stretches(records: Iterable[object], window_s: float = 120.0) -> list[Stretch]:
    """Straight, steady surface runs of up to ``window_s`` from a log's records (in time
    order): a turn, a change of RPM or a gap in the fixes ends one."""
    out: list[Stretch] = []
    fixes: list[Gps] = []
    headings: list[float] = []
    rpms: list[float] = []

    def close() -> None:
        if len(fixes) >= _MIN_FIXES:
            s = _stretch(fixes, headings, rpms)
            if s is not None:
                out.append(s)
        fixes.clear()
        headings.clear()
        rpms.clear()

    for rec in records:
        if isinstance(rec, Gps):
            good = (
                rec.fix > 0
                and rec.lat is not None
                and rec.lon is not None
                and (rec.hdop is None or rec.hdop <= _MAX_HDOP)
            )
            if not good or (fixes and rec.t - fixes[-1].t > 2.5):
                close()  # a stretch is continuous fixes only
            if good:
                fixes.append(rec)
                if rec.t - fixes[0].t >= window_s:
                    close()
        elif isinstance(rec, Heading | Attitude) and fixes:
            h = rec.deg if isinstance(rec, Heading) else rec.yaw_deg
            if headings and abs((h - headings[0] + 180.0) % 360.0 - 180.0) > _MAX_TURN_DEG:
                close()  # a turn: what came before it is one stretch
            else:
                headings.append(h)
        elif isinstance(rec, Rpm) and fixes:
            if rpms and abs(rec.rpm - rpms[0]) > 0.05 * max(abs(rpms[0]), 1.0):
                close()
            else:
                rpms.append(rec.rpm)
    close()
    return out


def _stretch(fixes: list[Gps], headings: list[float], rpms: list[float]) -> Stretch | None:
    if not headings or not rpms or min(rpms) <= 0.0:
        return None  # not under way: the water track has no heading
    s = sum(math.sin(math.radians(h)) for h in headings)
    c = sum(math.cos(math.radians(h)) for h in headings)
    mean = math.degrees(math.atan2(s, c)) % 360.0
    lat0, lon0 = math.radians(fixes[0].lat or 0.0), math.radians(fixes[0].lon or 0.0)
    t = np.array([f.t for f in fixes])
    en = np.array(
        [
            geodesy.enu_offset(
                lat0, lon0, 0.0, math.radians(f.lat or 0.0), math.radians(f.lon or 0.0), 0.0
            )[:2]
            for f in fixes
        ]
    )
    tc = t - t.mean()
    denom = float(tc @ tc)
    if denom <= 0.0:
        return None
    ve, vn = (tc @ (en - en.mean(axis=0))) / denom
    if math.hypot(vn, ve) < _MIN_SPEED_MPS:
        return None
    return Stretch(float(t.mean()), mean, float(np.mean(rpms)), float(vn), float(ve))


@dataclass(frozen=True, slots=True)
class Fit:
    deviation_deg: list[float]  # A..E, or those given
    deviation_std_deg: list[float]
    rpm_per_mps: float
    rpm_per_mps_std: float
    offset_mps: float
    offset_std_mps: float
    current_n: float
    current_e: float
    residual_deg: float  # RMS of the heading of the water track against the fitted heading
    residual_mps: float
    stretches: int
    coverage_deg: float  # the headings' span: 360 less the widest gap between them


def coverage_deg(headings: Sequence[float]) -> float:
    hs = sorted(h % 360.0 for h in headings)
    if not hs:
        return 0.0
    gaps = [b - a for a, b in zip(hs, hs[1:], strict=False)] + [hs[0] + 360.0 - hs[-1]]
    return 360.0 - max(gaps)


def _check_support(
    runs: Sequence[Stretch], fit_deviation: bool, fit_offset: bool
) -> tuple[int, float]:
    """The number of unknowns and the headings' coverage (degrees), once the stretches
    are known to be enough for them."""
    need = 3 + (compass.TERMS if fit_deviation else 0) + (1 if fit_offset else 0)
    if 2 * len(runs) < need + 2:
        raise CalibrationError(
            f"{len(runs)} straight surface stretches: too few (run longer straight legs with GPS)"
        )
    cov = coverage_deg([r.compass_deg for r in runs])
    # the deviation's harmonics need headings all round; the speed, reciprocal runs at
    # least, or the current cannot be told from it
    max_gap = MAX_GAP_DEG if fit_deviation else 180.0
    if 360.0 - cov > max_gap:
        raise CalibrationError(
            f"the headings leave a gap of {360.0 - cov:.0f} deg (at most {max_gap:.0f}): "
            + ("run a full circle at the surface" if fit_deviation else "add reciprocal runs")
        )
    return need, cov


@dataclass(frozen=True)
class _Model:
    """The GPS velocity over ground the unknowns predict for each stretch: north
    velocities, then east (see the module's model)."""

    h: np.ndarray  # compass headings, degrees
    rpm: np.ndarray
    basis: np.ndarray  # the deviation curve's harmonics at each heading, n x TERMS
    fixed_dev: np.ndarray
    declination_deg: float
    fit_deviation: bool
    fit_offset: bool

    def unpack(self, th: np.ndarray) -> tuple[np.ndarray, float, float, float, float]:
        """Deviation terms, seconds per metre per RPM, speed offset, current n/e."""
        i = 0
        dev = self.fixed_dev
        if self.fit_deviation:
            dev, i = th[: compass.TERMS], compass.TERMS
        q = th[i]
        b = th[i + 1] if self.fit_offset else 0.0
        cn, ce = th[-2], th[-1]
        return dev, q, b, cn, ce

    def heading_rad(self, dev: np.ndarray) -> np.ndarray:
        psi: np.ndarray = np.radians(self.h - self.basis @ dev + self.declination_deg)
        return psi

    def __call__(self, th: np.ndarray) -> np.ndarray:
        dev, q, b, cn, ce = self.unpack(th)
        psi = self.heading_rad(dev)
        s = self.rpm * q + b
        out: np.ndarray = np.concatenate([s * np.cos(psi) + cn, s * np.sin(psi) + ce])
        return out


def _gauss_newton(model: _Model, th: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares unknowns from ``th``, and the Jacobian at the last step
    (central differences)."""
    jac = np.empty((g.size, th.size))
    for _ in range(30):
        r = model(th) - g
        jac = np.empty((g.size, th.size))
        for k in range(th.size):
            d = np.zeros_like(th)
            d[k] = 1e-6 * max(1.0, abs(th[k]))
            jac[:, k] = (model(th + d) - model(th - d)) / (2 * d[k])
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
        th = th + step
        if float(np.max(np.abs(step))) < 1e-10:
            break
    return th, jac


def fit(
    runs: Sequence[Stretch],
    declination_deg: float,
    rpm_per_mps: float,
    deviation: Sequence[float] = (),
    fit_deviation: bool = True,
    fit_offset: bool = False,
) -> Fit:
    """Fit the unknowns to the stretches (see the module's model)."""
    need, cov = _check_support(runs, fit_deviation, fit_offset)
    h = np.array([r.compass_deg for r in runs])
    g = np.concatenate([[r.vn for r in runs], [r.ve for r in runs]])
    fixed_dev = np.asarray(deviation, dtype=float) if len(deviation) else np.zeros(compass.TERMS)
    model = _Model(
        h,
        np.array([r.rpm for r in runs]),
        np.array([compass.basis(x) for x in h]),
        fixed_dev,
        declination_deg,
        fit_deviation,
        fit_offset,
    )
    th0 = np.zeros(need)
    if fit_deviation:
        th0[: compass.TERMS] = fixed_dev
    th0[compass.TERMS if fit_deviation else 0] = 1.0 / rpm_per_mps
    th, jac = _gauss_newton(model, th0, g)
    r = model(th) - g
    dof = max(1, g.size - th.size)
    sigma2 = float(r @ r) / dof
    try:
        cov_th = sigma2 * np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        raise CalibrationError("the stretches do not determine the fit (degenerate)") from None
    std = np.sqrt(np.maximum(np.diag(cov_th), 0.0))
    dev, q, b, cn, ce = model.unpack(th)
    if not (math.isfinite(q) and q > 0):
        raise CalibrationError("the fit gives no positive speed per RPM")
    i_q = compass.TERMS if fit_deviation else 0
    # heading residuals: the water track's direction against the fitted heading
    wn, we = g[: len(runs)] - cn, g[len(runs) :] - ce
    dpsi = np.degrees(np.arctan2(we, wn) - model.heading_rad(dev))
    dpsi = (dpsi + 180.0) % 360.0 - 180.0
    return Fit(
        deviation_deg=[float(x) for x in dev],
        deviation_std_deg=[float(x) for x in std[: compass.TERMS]] if fit_deviation else [],
        rpm_per_mps=1.0 / q,
        rpm_per_mps_std=float(std[i_q]) / q**2,
        offset_mps=float(b),
        offset_std_mps=float(std[i_q + 1]) if fit_offset else 0.0,
        current_n=float(cn),
        current_e=float(ce),
        residual_deg=float(np.sqrt(np.mean(dpsi**2))),
        residual_mps=float(np.sqrt(np.mean(r**2))),
        stretches=len(runs),
        coverage_deg=cov,
    )


def supports_offset(runs: Sequence[Stretch]) -> bool:
    """Runs at clearly different RPMs: enough to tell a speed offset from the scale."""
    rpms = [r.rpm for r in runs]
    return bool(rpms) and (max(rpms) - min(rpms)) > 0.3 * (sum(rpms) / len(rpms))
