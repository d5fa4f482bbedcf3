"""The posterior Cramér-Rao bound of a simulated mission: the best any estimator could do.

Tichavský, Muravchik and Nehorai, "Posterior Cramér-Rao bounds for discrete-time
nonlinear filtering", IEEE Trans. Signal Processing 46(5), 1998: for additive
Gaussian process and measurement noise, the information recursion is the Kalman
covariance recursion with every Jacobian taken at the true state.  That is what this
module runs, over the simulator's truth, with the simulator's own noise:

* states: position north/east, current north/east, heading bias, speed scale, the
  relative error of the crew's sound speed (every range's scale), and for each beacon
  the error of the position it reports (the boat's GPS, a first-order Gauss-Markov
  process with the boat's ``gps_std_m`` and ``gps_corr_s``; a transponder's survey
  error, constant with ``survey_std_m``);
* process noise: the compass and RPM noise of each sample (white at the sensor
  rate), and for the current a random walk as fast as the truth's current changes
  (its rate of change squared times ``CURRENT_MEMORY_S``: a tidal stream is not
  known to the estimator as a sinusoid);
* priors: position from the first GPS fix; each calibration state's std is the
  truth's own size, with a floor.  The bound is a mean over the prior: one taken
  wider than the errors a mission really has is not reached by any estimator on
  that mission, one taken narrower (the truth's value itself) is an estimator
  that was told the answer;
* measurements: GPS fixes as the simulator drew them, and the ranges an ideal
  outlier detector keeps (no multipath, no corrupted or missing beacon position:
  ``AcousticChannel.clean``), with the range noise and the transducer's swing.

Ranges sent while the boat's location line was down are left out, so in that
class the bound is that of an estimator that waits for the line.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from navd import geodesy
from navd.hil.world import SWING_MEMORY, SWING_STEP, Mission
from navd.records import Gps
from navd.settings import Config

# A current that changes is a random walk with the variance it would build in this long
# (how far back the ranges that measure the current reach).
CURRENT_MEMORY_S = 600.0
STEP_S = 1.0
SUBMERGED_DEPTH_M = 0.3
# the least prior std of each calibration state: what no crew knows better
FLOOR_CURRENT_MPS = 0.02
_FLOOR_BIAS_DEG = 0.5
_FLOOR_SCALE = 0.01
_FLOOR_SOUND = 0.001  # 1.5 m/s: a sound speed from a CTD cast
SOUND_STATE = 6  # the sound speed's state; the beacons' follow


@dataclass(frozen=True, slots=True)
class Bound:
    rms_m: float  # sqrt of the mean, over the submerged steps, of the position variance
    steps: int
    ranges: int  # ranges the ideal detector kept
    # the position covariance at each submerged step: (t, var_n, var_e, cov_ne), m^2, so
    # that an estimate's ellipse can be set beside the least any estimator could claim
    ellipses: tuple[tuple[float, float, float, float], ...] = ()


def local_ne(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    """North and east of (lat0, lon0), metres, degrees in (navd's local tangent plane)."""
    e, n, _ = geodesy.enu_offset(
        math.radians(lat0), math.radians(lon0), 0.0, math.radians(lat), math.radians(lon), 0.0
    )
    return n, e


def truth_current_rate(m: Mission, i: int, j: int) -> float:
    """Squared rate of change (per axis, mean of the two) of the true current from i to j."""
    a, b = m.truth[i], m.truth[j]
    dt = max(b.t - a.t, 1e-9)
    return 0.5 * (((b.current_n - a.current_n) / dt) ** 2 + ((b.current_e - a.current_e) / dt) ** 2)


def calibration_prior(m: Mission, cfg: Config, col: dict[str, int]) -> np.ndarray:
    """Each calibration state's std is the truth's own size (an estimator that knows how
    large the error is, not what it is), with a floor; no position until the first fix."""
    sc, s, tr = m.scenario, m.scenario.sensors, m.truth
    c_true = math.hypot(tr[0].current_n, tr[0].current_e) / math.sqrt(2.0)
    bias_true = math.radians(abs(s.compass_bias_deg) + sum(abs(x) for x in s.compass_deviation_deg))
    scale_true = abs(cfg.navigation.speed.rpm_per_mps / s.rpm_per_mps - 1.0)
    n_states = SOUND_STATE + 1 + 2 * len(col)
    P = np.zeros((n_states, n_states))
    P[0, 0] = P[1, 1] = 1e8
    P[2, 2] = P[3, 3] = max(FLOOR_CURRENT_MPS, c_true) ** 2
    P[4, 4] = max(math.radians(_FLOOR_BIAS_DEG), bias_true) ** 2
    P[5, 5] = max(_FLOOR_SCALE, scale_true) ** 2
    P[SOUND_STATE, SOUND_STATE] = max(_FLOOR_SOUND, abs(sound_error(m, cfg))) ** 2
    fixed = sc.acoustics.transponders
    for name, k in col.items():
        std = next((tp.survey_std_m for tp in fixed if tp.name == name), sc.boat.gps_std_m)
        P[k, k] = P[k + 1, k + 1] = max(std, 1e-3) ** 2
    return P


def sound_error(m: Mission, cfg: Config) -> float:
    """The water's sound speed over the one the crew's config gives, less one: each range
    navd computes is the true one over (1 + this)."""
    sc = m.scenario
    depth = 0.5 * (sc.vehicle.depth_m + sc.boat.transducer_depth_m)
    return m.channel.c_water / cfg.navigation.sound_speed.model_obj().at(depth) - 1.0


def range_variance(m: Mission) -> float:
    """A range's noise variance: the modem's, and for a boat's transducer its swing (the
    stationary variance per axis of an AR(1) process held within swing_m)."""
    sc, b = m.scenario, m.scenario.boat
    if sc.acoustics.transponders:
        return sc.acoustics.range_noise_m**2
    step2 = (SWING_STEP * b.swing_m) ** 2 / sc.sensors.rate_hz
    swing_var = min(b.swing_m**2, step2 / (1.0 - SWING_MEMORY**2))
    return sc.acoustics.range_noise_m**2 + swing_var


def input_noise(
    psi: float, u: float, sig_psi: float, sig_u: float, rate: float, dt: float
) -> np.ndarray:
    """The position noise (north, east; m^2) over ``dt`` of heading ``psi`` (radians) and
    speed ``u`` measured with white errors of stds ``sig_psi`` and ``sig_u`` at ``rate``."""
    if u <= 0.0:
        return np.zeros((2, 2))
    c, sn = math.cos(psi), math.sin(psi)
    var_along = sig_u**2 / rate * dt
    var_cross = (u * sig_psi) ** 2 / rate * dt
    cross = (var_along - var_cross) * c * sn
    return np.array(
        [
            [var_along * c * c + var_cross * sn * sn, cross],
            [cross, var_along * sn * sn + var_cross * c * c],
        ]
    )


def current_walk(m: Mission, i: int, j: int, dt: float) -> float:
    """The current's walk variance (per axis, (m/s)^2) over ``dt`` from truth sample i to j:
    as fast as the truth's current changes there."""
    return truth_current_rate(m, i, j) * CURRENT_MEMORY_S * dt


# the parts of the bound's model matched_config can give navd, and the noise keys of each
MATCHED_PARTS: dict[str, tuple[str, ...]] = {
    "ranges": ("range_std_m",),
    "inputs": ("heading_std_deg", "speed_std_mps", "input_corr_s"),
    "priors": ("current_init_std_mps", "heading_bias_init_std_deg", "speed_scale_init_std"),
    "current": ("current_walk_mps_per_sqrt_s",),
    "calibration": ("heading_bias_walk_deg_per_sqrt_s", "speed_scale_walk_per_sqrt_s"),
    "gps": ("gps_std_m",),
}


def matched_config(
    m: Mission, cfg: Config, parts: Collection[str] = tuple(MATCHED_PARTS)
) -> dict[str, object]:
    """Config overrides that give navd's default mode the bound's own model of ``m``: its
    sensor noise (white at the sensor rate), range noise, priors as large as the
    mission's errors, a current walk as fast as the truth's current changes over the
    mission (as a mean square), no calibration walks, and the boat's GPS error; or only
    the ``parts`` of it named (MATCHED_PARTS; the sound speed's prior goes with the
    priors, the boat's GPS with gps).

    Not a config for a vehicle (a crew knows none of this): it separates the cost of the
    default's conservative noise model from what the filter itself loses (bench
    robustness ``--matched-noise``), and each part's share of that cost."""
    sc, s, tr = m.scenario, m.scenario.sensors, m.truth
    P = calibration_prior(m, cfg, {})  # the calibration's priors (no beacon states)
    stride = max(1, round(STEP_S * s.rate_hz))
    rates = [truth_current_rate(m, i, i + stride) for i in range(0, len(tr) - stride, stride)]
    walk = math.sqrt(CURRENT_MEMORY_S * (sum(rates) / len(rates))) if rates else 0.0
    noise = {
        "range_std_m": math.sqrt(range_variance(m)),
        "heading_std_deg": max(s.compass_noise_deg, 1e-3),
        "speed_std_mps": max(s.rpm_noise / s.rpm_per_mps, 1e-4),
        "input_corr_s": 1.0 / s.rate_hz,
        "current_init_std_mps": math.sqrt(P[2, 2]),
        "heading_bias_init_std_deg": math.degrees(math.sqrt(P[4, 4])),
        "speed_scale_init_std": math.sqrt(P[5, 5]),
        "current_walk_mps_per_sqrt_s": walk,
        "heading_bias_walk_deg_per_sqrt_s": 0.0,
        "speed_scale_walk_per_sqrt_s": 0.0,
        "gps_std_m": max(s.gps_std_m, 0.1),
    }
    keys = {k for part in parts for k in MATCHED_PARTS[part]}
    nav: dict[str, object] = {"noise": {k: v for k, v in noise.items() if k in keys}}
    if "priors" in parts:
        c_crew = cfg.navigation.sound_speed.model_obj().at(0.0)
        nav["sound_speed"] = {"std_mps": math.sqrt(P[SOUND_STATE, SOUND_STATE]) * c_crew}
    out: dict[str, object] = {"navigation": nav}
    if "gps" in parts and not sc.acoustics.transponders:
        b = sc.boat
        out["beacons"] = {"udb": {"position_std_m": b.gps_std_m, "position_corr_s": b.gps_corr_s}}
    return out


def ideal_measurements(m: Mission, col: dict[str, int]) -> list[tuple[float, str, float | str]]:
    """In time order: ("gps", t, std) and ("range", t, beacon) for the clean replies."""
    s = m.scenario.sensors
    meas: list[tuple[float, str, float | str]] = []
    for rec in m.records:
        if isinstance(rec, Gps) and rec.lat is not None:
            hdop = rec.hdop or 1.0
            warm = max(0.0, (hdop - 1.0) / 3.0)
            meas.append((rec.t, "gps", s.gps_std_m + warm * s.gps_warmup_std_m))
    for t, name in m.channel.clean:
        if name in col:
            meas.append((t, "range", name))
    meas.sort(key=lambda x: x[0])
    return meas


def mission_bound(m: Mission, cfg: Config) -> Bound:
    sc = m.scenario
    s = sc.sensors
    tr = m.truth
    rate = s.rate_hz
    stride = max(1, round(STEP_S * rate))
    lat0, lon0 = tr[0].lat, tr[0].lon

    # beacons and the states of their position errors
    fixed = list(sc.acoustics.transponders)
    names = [tp.name for tp in fixed] if fixed else ["udb"]
    where: dict[str, tuple[float, float, float]] = {}
    for tp in fixed:
        where[tp.name] = (tp.north_m, tp.east_m, tp.depth_m)
    n_states = SOUND_STATE + 1 + 2 * len(names)
    col = {name: SOUND_STATE + 1 + 2 * k for k, name in enumerate(names)}

    P = calibration_prior(m, cfg, col)
    b = sc.boat

    sig_psi = math.radians(s.compass_noise_deg)
    sig_u = s.rpm_noise / s.rpm_per_mps
    r_var = range_variance(m)
    phi_boat = math.exp(-STEP_S / b.gps_corr_s)

    meas = ideal_measurements(m, col)
    first_fix = next((t for t, kind, _ in meas if kind == "gps"), None)
    if first_fix is None:
        return Bound(math.nan, 0, 0)

    sub_var: list[float] = []
    ellipses: list[tuple[float, float, float, float]] = []
    used = 0
    mi = 0
    started = False
    for i in range(0, len(tr) - stride, stride):
        a = tr[i]
        t_next = tr[i + stride].t
        # measurements in [a.t, t_next)
        while mi < len(meas) and meas[mi][0] < t_next:
            t, kind, arg = meas[mi]
            mi += 1
            if kind == "gps":
                started = True
                H = np.zeros((2, n_states))
                H[0, 0] = H[1, 1] = 1.0
                S = H @ P @ H.T + np.eye(2) * float(arg) ** 2
                P = P - P @ H.T @ np.linalg.solve(S, H @ P)
            elif started:
                j = min(len(tr) - 1, int(round(t * rate)))
                v = tr[j]
                pn, pe = local_ne(lat0, lon0, v.lat, v.lon)
                if fixed:
                    bn, be, bdepth = where[str(arg)]
                else:
                    bn, be = local_ne(lat0, lon0, v.boat_lat, v.boat_lon)
                    bdepth = b.transducer_depth_m
                dn, de, dz = pn - bn, pe - be, v.depth - bdepth
                slant = math.sqrt(dn * dn + de * de + dz * dz)
                if slant < 1e-3:
                    continue
                h = np.zeros(n_states)
                h[0], h[1] = dn / slant, de / slant
                k = col[str(arg)]
                h[k], h[k + 1] = -h[0], -h[1]
                h[SOUND_STATE] = -slant  # the range navd computes, over its sound speed's error
                Ph = P @ h
                P = P - np.outer(Ph, Ph) / (float(h @ Ph) + r_var)
                used += 1
        if started and a.depth >= SUBMERGED_DEPTH_M:
            sub_var.append(float(P[0, 0] + P[1, 1]))
            ellipses.append((a.t, float(P[0, 0]), float(P[1, 1]), float(P[0, 1])))
        # propagate over the step with the Jacobians at the truth
        dt = t_next - a.t
        psi, u = math.radians(a.heading_deg), a.speed_mps
        c, sn = math.cos(psi), math.sin(psi)
        F = np.eye(n_states)
        F[0, 2] = F[1, 3] = dt
        F[0, 4], F[1, 4] = -u * sn * dt, u * c * dt
        F[0, 5], F[1, 5] = u * c * dt, u * sn * dt
        Q = np.zeros((n_states, n_states))
        Q[0:2, 0:2] = input_noise(psi, u, sig_psi, sig_u, rate, dt)
        Q[2, 2] = Q[3, 3] = current_walk(m, i, i + stride, dt)
        if not fixed:
            k = col["udb"]
            F[k, k] = F[k + 1, k + 1] = phi_boat
            Q[k, k] = Q[k + 1, k + 1] = b.gps_std_m**2 * (1.0 - phi_boat**2)
        P = F @ P @ F.T + Q
        P = 0.5 * (P + P.T)
    if not sub_var:
        return Bound(math.nan, 0, used)
    return Bound(math.sqrt(float(np.mean(sub_var))), len(sub_var), used, tuple(ellipses))
