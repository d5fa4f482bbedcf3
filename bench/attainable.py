"""How near the posterior Cramer-Rao bound an estimator can come, on the bound's own model.

The bound (navd/hil/bound.py) takes every Jacobian at the truth; no estimator knows the
truth, so for a nonlinear problem the bound may not be reachable at all, and a target set
against it may ask for more than any filter can give.  This bench asks how much more, with
no help from navd and no model mismatch:

* measurements are drawn from the bound's own model along the simulator's truth of each
  Monte Carlo mission (bench/robustness.py's draws): the compass and RPM noise white at the
  sensor rate, the calibration errors the mission's (heading bias, speed scale, the crew's
  sound speed error), the boat's GPS error as a Gauss-Markov process, surveyed transponders
  off by their survey error, the clean ranges the ideal outlier detector keeps, at the times
  the simulator made them, with the bound's range noise;
* two reference estimators know that model exactly (its noise, its priors, the current's
  walk): an extended Kalman filter, and the full-information estimate, which at each
  evaluation time solves the whole past again by Gauss-Newton (the iterated Kalman
  smoother, Bell 1994: every range linearised where all the later ones put the vehicle),
  the most a causal estimator can draw from a Gaussian model short of carrying the whole
  posterior;
* navd's default mode (its bank of two range EKFs with their windows, gates and range
  biases, navd/filter/bank.py) is given the same measurements, configured with the bound's
  model as ``--matched-noise`` configures it (navd/hil/bound.py ``matched_config``);
* with ``--tide`` or ``--tide-std``, an EKF and a full-information estimate that carry the
  tide's form as well (``Tide``: its semidiurnal constituents as states, the issue's other
  way to model a current that changes) are flown on the missions whose water has a tide,
  beside the two with the walk;
* each is scored, every ``EVAL_S`` seconds of submerged time, as RMS position error over
  the bound's RMS at the same instants.

What the full-information estimate cannot reach, no filter navd could run reaches either;
where navd's filter reaches what the references reach, its distance from the bound on the
simulator's missions is the simulator's data against the bound's model, not the filter.
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.common import write_section
from bench.robustness import CLASSES, draw
from navd import geodesy
from navd.analysis.jobs import default_jobs
from navd.filter.bank import M2_PERIOD_S
from navd.filter.common import RangeMeas
from navd.filter.navparts import make_filter
from navd.hil.bound import (
    FLOOR_CURRENT_MPS,
    SOUND_STATE,
    STEP_S,
    SUBMERGED_DEPTH_M,
    calibration_prior,
    current_walk,
    ideal_measurements,
    input_noise,
    local_ne,
    matched_config,
    mission_bound,
    range_variance,
    sound_error,
)
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import mission_config
from navd.hil.world import Mission, simulate
from navd.settings import Config, config_from_dict, deep_merge

EVAL_S = 60.0  # one evaluation a minute of submerged time
_ITERATIONS = 3  # Gauss-Newton passes per evaluation (warm started from the last)


@dataclass(frozen=True)
class Tide:
    """An estimator that knows the tide's form, the issue's "tidal constituents as states":
    the water runs at the mean current plus ``a cos(wt) + b sin(wt)`` (``a``, ``b`` north
    and east, four states, constant, each with prior std ``std_mps``) at the principal
    lunar semidiurnal frequency.  The mean current keeps ``walk_share`` of the bound's
    walk: the Monte Carlo's water changes only by its tide, so by default none."""

    std_mps: float
    omega: float = 2.0 * math.pi / M2_PERIOD_S
    walk_share: float = 0.0

    @staticmethod
    def for_mission(
        m: Mission,
        factor: float | None,
        std_mps: float | None,
        everywhere: bool = False,
        walk_share: float = 0.0,
    ) -> Tide | None:
        """The tide a crew would configure for ``m``: each constituent's std ``factor`` times
        the mission's own amplitude over sqrt 2 (a tidal current prediction that far off),
        or ``std_mps``; None where the mission has no tide, unless ``everywhere`` (with
        ``std_mps``: a prior for water whose tide nobody predicted, which may have none).
        The mean current keeps ``walk_share`` of the bound's walk."""
        amp = m.scenario.current.tidal_amplitude_mps
        if amp <= 0.0 and not (everywhere and std_mps is not None):
            return None
        if std_mps is None:
            std_mps = (factor or 1.0) * amp / math.sqrt(2.0)
        return Tide(max(FLOOR_CURRENT_MPS, std_mps), walk_share=walk_share)


def _rot(b: float) -> np.ndarray:
    c, s = math.cos(b), math.sin(b)
    return np.array([[c, -s], [s, c]])


def _drot(b: float) -> np.ndarray:
    c, s = math.cos(b), math.sin(b)
    return np.array([[-s, -c], [c, -s]])


@dataclass
class Node:
    """A step of the bound's grid that carries measurements or is scored."""

    k: int
    gps: list[tuple[np.ndarray, float]] = field(default_factory=list)
    # (range, reported beacon north and east, depth difference, beacon's state column)
    ranges: list[tuple[float, np.ndarray, float, int]] = field(default_factory=list)
    scored: bool = False


@dataclass
class Generated:
    """A mission's measurements drawn from the bound's model, and what to score them by."""

    nodes: list[Node]
    truth_x: np.ndarray  # (steps + 1, states): the model's true state at each step
    d_meas: np.ndarray  # (steps, 2) each step's measured displacement through the water
    q_in: np.ndarray  # (steps, 2, 2) its noise, as the vehicle's own displacement
    q_walk: np.ndarray  # (steps,) the current's walk variance over the step, per axis
    dt: float
    P0: np.ndarray
    boat_cols: tuple[int, ...]  # the states of a reported (wandering) position's error
    boat_var: float
    boat_corr_s: float
    bound_var: dict[int, float]  # step -> the bound's var_n + var_e
    origin: tuple[float, float] = (0.0, 0.0)  # degrees: the truth's first position
    depth: np.ndarray = field(default_factory=lambda: np.zeros(0))  # vehicle, each step
    beacon_std: dict[int, tuple[float, float]] = field(default_factory=dict)  # col -> std, corr
    names: dict[int, str] = field(default_factory=dict)  # col -> beacon name


def generate(
    m: Mission, cfg: Config, rng: np.random.Generator, walk_current: bool = False
) -> Generated | None:
    """Mission ``m``'s measurements from the bound's model along its truth; with
    ``walk_current``, the truth's current replaced by one drawn from the bound's own walk
    (the vehicle moving through the water as before, carried by that current instead)."""
    sc, s, tr = m.scenario, m.scenario.sensors, m.truth
    rate = s.rate_hz
    stride = max(1, round(STEP_S * rate))
    lat0, lon0 = tr[0].lat, tr[0].lon
    steps = (len(tr) - 1) // stride
    if steps < 2:
        return None
    fixed = list(sc.acoustics.transponders)
    names = [tp.name for tp in fixed] if fixed else ["udb"]
    col = {name: SOUND_STATE + 1 + 2 * k for k, name in enumerate(names)}
    n_states = SOUND_STATE + 1 + 2 * len(names)
    P0 = calibration_prior(m, cfg, col)

    idx = [k * stride for k in range(steps + 1)]
    t_grid = np.array([tr[i].t for i in idx])
    p = np.array([local_ne(lat0, lon0, tr[i].lat, tr[i].lon) for i in idx])
    c = np.array([(tr[i].current_n, tr[i].current_e) for i in idx])
    dt = float(t_grid[1] - t_grid[0])

    bias = math.radians(s.compass_bias_deg)
    scale = cfg.navigation.speed.rpm_per_mps / s.rpm_per_mps - 1.0
    sound = sound_error(m, cfg)
    sig_psi = math.radians(s.compass_noise_deg)
    sig_u = s.rpm_noise / s.rpm_per_mps
    q_in = np.zeros((steps, 2, 2))
    q_walk = np.zeros(steps)
    d_meas = np.zeros((steps, 2))
    r_inv = _rot(-bias)
    for k in range(steps):
        a = tr[idx[k]]
        q_in[k] = input_noise(math.radians(a.heading_deg), a.speed_mps, sig_psi, sig_u, rate, dt)
        w = rng.multivariate_normal(np.zeros(2), q_in[k]) if a.speed_mps > 0.0 else np.zeros(2)
        q_walk[k] = current_walk(m, idx[k], idx[k + 1], dt)
        d_meas[k] = r_inv @ (p[k + 1] - p[k] - c[k] * dt - w) / (1.0 + scale)
    if walk_current:
        walked = c[0] + np.vstack(
            [
                np.zeros((1, 2)),
                np.cumsum(rng.normal(0.0, 1.0, (steps, 2)) * np.sqrt(q_walk)[:, None], axis=0),
            ]
        )
        p = p + np.vstack([np.zeros((1, 2)), np.cumsum((walked - c)[:-1] * dt, axis=0)])
        c = walked

    # the beacons' position errors: a boat's GPS wanders, a survey's stays
    b = sc.boat
    phi = math.exp(-dt / b.gps_corr_s)
    err = np.zeros((steps + 1, n_states))
    for tp in fixed:
        k0 = col[tp.name]
        err[:, k0 : k0 + 2] = rng.normal(0.0, max(tp.survey_std_m, 1e-3), 2)
    if not fixed:
        k0 = col["udb"]
        e = rng.normal(0.0, b.gps_std_m, 2)
        for k in range(steps + 1):
            err[k, k0 : k0 + 2] = e
            e = phi * e + rng.normal(0.0, b.gps_std_m * math.sqrt(1.0 - phi * phi), 2)
    where = {tp.name: (tp.north_m, tp.east_m, tp.depth_m) for tp in fixed}
    r_std = math.sqrt(range_variance(m))

    nodes: dict[int, Node] = {}
    started = False
    for t, kind, arg in ideal_measurements(m, col):
        k = int(np.searchsorted(t_grid, t, side="right")) - 1
        if k < 0 or k >= steps:
            continue
        if kind == "gps":
            started = True
            std = float(arg)
            z = p[k] + rng.normal(0.0, std, 2)
            nodes.setdefault(k, Node(k)).gps.append((z, std))
        elif started:
            v = tr[idx[k]]
            name = str(arg)
            if fixed:
                bn, be, bdepth = where[name]
            else:
                bn, be = local_ne(lat0, lon0, v.boat_lat, v.boat_lon)
                bdepth = b.transducer_depth_m
            dz = v.depth - bdepth
            k0 = col[name]
            rel = p[k] - np.array([bn, be])
            slant = math.sqrt(float(rel @ rel) + dz * dz)
            if slant < 1e-3:
                continue
            z = slant / (1.0 + sound) + rng.normal(0.0, r_std)
            reported = np.array([bn, be]) + err[k, k0 : k0 + 2]
            nodes.setdefault(k, Node(k)).ranges.append((z, reported, dz, k0))
    fixes = [k for k, nd in nodes.items() if nd.gps]
    if not fixes:
        return None
    first = min(fixes)  # as the bound, from the first fix
    bnd = mission_bound(m, cfg)
    by_t = {round(e[0], 6): e[1] + e[2] for e in bnd.ellipses}
    bound_var: dict[int, float] = {}
    next_eval = -math.inf
    for k in range(first, steps):
        if tr[idx[k]].depth < SUBMERGED_DEPTH_M or t_grid[k] < next_eval:
            continue
        var = by_t.get(round(float(t_grid[k]), 6))
        if var is None:
            continue
        next_eval = float(t_grid[k]) + EVAL_S
        nodes.setdefault(k, Node(k)).scored = True
        bound_var[k] = var
    order = [nodes[k] for k in sorted(nodes) if k >= first]
    boat_cols = () if fixed else (col["udb"], col["udb"] + 1)
    truth_x = err  # the beacons' errors, and the rest of the state beside them
    truth_x[:, 0:2] = p
    truth_x[:, 2:4] = c
    truth_x[:, 4:7] = bias, scale, sound
    beacon_std = {col[tp.name]: (tp.survey_std_m, 1e9) for tp in fixed}
    if not fixed:
        beacon_std[col["udb"]] = (b.gps_std_m, b.gps_corr_s)
    return Generated(
        order, truth_x, d_meas, q_in, q_walk, dt, P0, boat_cols, b.gps_std_m**2, b.gps_corr_s,
        bound_var, (lat0, lon0), np.array([tr[i].depth for i in idx]), beacon_std,
        {k: name for name, k in col.items()},
    )  # fmt: skip


class Model:
    """The bound's model between and at the nodes, for an estimator that knows it."""

    def __init__(self, g: Generated, r_var: float, tide: Tide | None = None) -> None:
        self.g = g
        self.r_var = r_var  # a range's noise variance
        self.tide = tide
        nb = g.P0.shape[0]
        # with the tide's form, its four constituent states follow the bound's
        self.tide_col = nb
        self.n = nb + (4 if tide else 0)
        self.P0 = np.zeros((self.n, self.n))
        self.P0[:nb, :nb] = g.P0
        if tide:
            self.P0[nb:, nb:] = tide.std_mps**2 * np.eye(4)
        self.walk_share = tide.walk_share if tide else 1.0
        # prefix sums over steps, so that a transition between any two nodes is O(1)
        steps = len(g.d_meas)
        j = np.arange(steps, dtype=float)
        self.cd = np.vstack([np.zeros((1, 2)), np.cumsum(g.d_meas, axis=0)])
        self.cq = np.concatenate([[[[0.0, 0.0], [0.0, 0.0]]], np.cumsum(g.q_in, axis=0)])
        self.s0 = np.concatenate([[0.0], np.cumsum(g.q_walk)])
        self.s1 = np.concatenate([[0.0], np.cumsum(j * g.q_walk)])
        self.s2 = np.concatenate([[0.0], np.cumsum(j * j * g.q_walk)])

    def transition(
        self, ka: int, kb: int, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f(x), its Jacobian, and the process noise from step ka to kb."""
        g, n = self.g, self.n
        m = kb - ka
        D = self.cd[kb] - self.cd[ka]
        b, sc = float(x[4]), float(x[5])
        R = _rot(b)
        fx = x.copy()
        fx[0:2] = x[0:2] + m * g.dt * x[2:4] + (1.0 + sc) * (R @ D)
        F = np.eye(n)
        F[0, 2] = F[1, 3] = m * g.dt
        F[0:2, 4] = (1.0 + sc) * (_drot(b) @ D)
        F[0:2, 5] = R @ D
        Q = np.zeros((n, n))
        s0 = self.s0[kb] - self.s0[ka]
        s1 = self.s1[kb] - self.s1[ka]
        s2 = self.s2[kb] - self.s2[ka]
        last = kb - 1
        w_pp = g.dt**2 * (last * last * s0 - 2.0 * last * s1 + s2)
        w_pc = g.dt * (last * s0 - s1)
        f = self.walk_share
        Q[0:2, 0:2] = self.cq[kb] - self.cq[ka] + f * w_pp * np.eye(2)
        Q[0:2, 2:4] = Q[2:4, 0:2] = f * w_pc * np.eye(2)
        Q[2:4, 2:4] = f * s0 * np.eye(2)
        if self.tide:
            # position integrates a cos(wt) + b sin(wt) from step ka to kb; a, b constant
            w = self.tide.omega
            t1, t2 = ka * g.dt, kb * g.dt
            ic = (math.sin(w * t2) - math.sin(w * t1)) / w
            is_ = (math.cos(w * t1) - math.cos(w * t2)) / w
            c = self.tide_col
            for a in range(2):
                fx[a] += ic * x[c + a] + is_ * x[c + 2 + a]
                F[a, c + a] = ic
                F[a, c + 2 + a] = is_
        if g.boat_cols:
            phi = math.exp(-m * g.dt / g.boat_corr_s)
            for c in g.boat_cols:
                fx[c] = phi * x[c]
                F[c, c] = phi
                Q[c, c] = g.boat_var * (1.0 - phi * phi)
        return fx, F, Q

    def measurements(
        self, nd: Node, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """z, h(x), H and R of a node's measurements."""
        n = self.n
        zs: list[float] = []
        hs: list[float] = []
        Hs: list[np.ndarray] = []
        rs: list[float] = []
        for z, std in nd.gps:
            for a in range(2):
                row = np.zeros(n)
                row[a] = 1.0
                zs.append(float(z[a]))
                hs.append(float(x[a]))
                Hs.append(row)
                rs.append(std * std)
        r_var = self.r_var
        for measured, reported, dz, k0 in nd.ranges:
            rel = x[0:2] - (reported - x[k0 : k0 + 2])
            slant = math.sqrt(float(rel @ rel) + dz * dz)
            one = 1.0 + float(x[SOUND_STATE])
            row = np.zeros(n)
            row[0:2] = rel / slant / one
            row[k0 : k0 + 2] = rel / slant / one
            row[SOUND_STATE] = -slant / one**2
            zs.append(measured)
            hs.append(slant / one)
            Hs.append(row)
            rs.append(r_var)
        return np.array(zs), np.array(hs), np.array(Hs).reshape(len(zs), n), np.diag(rs)


def _update(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, hx: np.ndarray, H: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    if len(z) == 0:
        return x, P
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    x = x + K @ (z - hx)
    I_KH = np.eye(len(x)) - K @ H
    P = I_KH @ P @ I_KH.T + K @ R @ K.T
    return x, 0.5 * (P + P.T)


def ekf(model: Model, nis: list[float] | None = None) -> list[np.ndarray]:
    """The extended Kalman filter: each node's filtered state; with ``nis``, each range's
    normalised innovation squared appended to it (1 on average for a filter whose
    covariance is its error's)."""
    g = model.g
    x = np.zeros(model.n)
    P = model.P0.copy()
    out: list[np.ndarray] = []
    prev = None
    for nd in g.nodes:
        if prev is not None:
            x, F, Q = model.transition(prev, nd.k, x)
            P = F @ P @ F.T + Q
        z, hx, H, R = model.measurements(nd, x)
        if nis is not None:
            for row, zi, hi, ri in zip(H[2 * len(nd.gps) :], z[2 * len(nd.gps) :],
                                       hx[2 * len(nd.gps) :], np.diag(R)[2 * len(nd.gps) :],
                                       strict=True):  # fmt: skip
                nis.append((zi - hi) ** 2 / float(row @ P @ row + ri))
        x, P = _update(x, P, z, hx, H, R)
        out.append(x.copy())
        prev = nd.k
    return out


def smooth(
    model: Model, nodes: Sequence[Node], lin: list[np.ndarray]
) -> tuple[list[np.ndarray], np.ndarray]:
    """One Gauss-Newton pass: the Kalman smoother of the model linearised along ``lin``.
    Returns the new trajectory and the last node's covariance."""
    n = model.n
    xf: list[np.ndarray] = []
    Pf: list[np.ndarray] = []
    xp: list[np.ndarray] = []
    Pp: list[np.ndarray] = []
    Fs: list[np.ndarray] = []
    x = np.zeros(n)
    P = model.P0.copy()
    for i, nd in enumerate(nodes):
        if i > 0:
            fx, F, Q = model.transition(nodes[i - 1].k, nd.k, lin[i - 1])
            x = fx + F @ (x - lin[i - 1])
            P = F @ P @ F.T + Q
            Fs.append(F)
        xp.append(x)
        Pp.append(P)
        z, hx, H, R = model.measurements(nd, lin[i])
        x, P = _update(x, P, z - hx + H @ lin[i], H @ x, H, R) if len(z) else (x, P)
        xf.append(x)
        Pf.append(P)
    xs = [xf[-1]]
    for i in range(len(nodes) - 2, -1, -1):
        G = np.linalg.solve(Pp[i + 1], Fs[i] @ Pf[i]).T
        xs.append(xf[i] + G @ (xs[-1] - xp[i + 1]))
    xs.reverse()
    return xs, Pf[-1]


def navd_core(g: Generated, cfg: Config, r_std: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """navd's default mode (its bank of two range EKFs, their windows and gates), configured
    with the bound's model, on the same measurements: at each scored node, its north and
    east and their published covariance."""
    flt = make_filter(cfg)
    lat0, lon0 = (math.radians(v) for v in g.origin)

    def geo(ne: np.ndarray) -> tuple[float, float]:
        return geodesy.offset_position(lat0, lon0, float(ne[0]), float(ne[1]))

    out: list[tuple[np.ndarray, np.ndarray]] = []
    prev: int | None = None
    sub = 10  # navd predicts at its 10 Hz tick
    for nd in g.nodes:
        if prev is not None and flt.initialised:
            for k in range(prev, nd.k):
                d = g.d_meas[k]
                heading = math.atan2(float(d[1]), float(d[0]))
                speed = math.hypot(float(d[0]), float(d[1])) / g.dt
                for j in range(1, sub + 1):
                    t = (k + j / sub) * g.dt
                    flt.predict(t, g.dt / sub, heading, speed, -float(g.depth[k]))
        prev = nd.k
        t = nd.k * g.dt
        for z, std in nd.gps:
            lat, lon = geo(z)
            if not flt.initialised:
                flt.initialise(lat, lon, std, t)
            else:
                flt.gps_update(lat, lon, std, 0.0)
        for measured, reported, dz, k0 in nd.ranges:
            if not flt.initialised:
                continue
            blat, blon = geo(reported)
            std, corr = g.beacon_std[k0]
            flt.range_update(
                RangeMeas(
                    t, t, measured, g.names[k0], blat, blon, -(float(g.depth[nd.k]) - dz),
                    -float(g.depth[nd.k]), r_std, std, corr,
                )
            )  # fmt: skip
        if nd.scored:
            est = flt.estimate()
            e, n, _ = geodesy.enu_offset(lat0, lon0, 0.0, est.lat, est.lon, 0.0)
            cov = np.array([[est.var_n, est.cov_ne], [est.cov_ne, est.var_e]])
            out.append((np.array([n, e]), cov))
    return out


_IN95 = 5.991  # chi-square, 2 degrees of freedom, 0.95
_BOOTSTRAP = 2000


def _inside95(err: np.ndarray, cov: np.ndarray) -> bool:
    return float(err @ np.linalg.solve(cov, err)) <= _IN95


@dataclass(frozen=True)
class Scored:
    """One run: RMS position errors at the scored instants (m), and how often the truth lay
    in each estimator's own 95 % ellipse."""

    seed: int
    cls: str
    kind: str
    scored: int
    bound_m: float
    ekf_m: float
    full_m: float
    full_in95: float
    navd_m: float
    navd_in95: float
    seconds: float
    tide_m: float = math.nan  # the EKF that knows the tide's form; nan where not flown
    tide_full_m: float = math.nan  # the full-information estimate that knows it


def _solve_to(model: Model, traj: list[np.ndarray], i: int) -> tuple[np.ndarray, np.ndarray]:
    """The full-information estimate at node ``i``: the whole past solved again, from where
    the last solve and the filter since left it (``traj``, updated in place); its state and
    covariance."""
    cur = traj[: i + 1]
    P = np.eye(model.n)
    for _ in range(_ITERATIONS):
        cur, P = smooth(model, model.g.nodes[: i + 1], cur)
    traj[: i + 1] = cur
    return cur[-1], P


def run_one(
    seed: int,
    draw_no: int = 0,
    walk_current: bool = False,
    tide_factor: float | None = None,
    tide_std: float | None = None,
    tide_everywhere: bool = False,
    tide_walk: float = 0.0,
) -> Scored | None:
    """Mission ``seed`` of bench/robustness.py, with the ``draw_no``-th draw of the bound's
    noise along its truth (with ``walk_current``, its current drawn from the bound's walk);
    with ``tide_factor`` or ``tide_std``, an EKF and a full-information estimate that know
    the tide's form as well (:meth:`Tide.for_mission`, with ``tide_everywhere`` and
    ``tide_walk``)."""
    t0 = time.perf_counter()
    dr = draw(seed)
    m = simulate(scenario_from_dict(dr.scenario), seed)
    cfg = config_from_dict(mission_config(m))
    g = generate(m, cfg, np.random.default_rng([seed, draw_no]), walk_current)
    if g is None or not g.bound_var:
        return None
    model = Model(g, range_variance(m))
    lin = ekf(model)
    tide = None
    if tide_factor is not None or tide_std is not None:
        tide = Tide.for_mission(m, tide_factor, tide_std, tide_everywhere, tide_walk)
    tide_model = Model(g, model.r_var, tide) if tide else None
    tidal = ekf(tide_model) if tide_model else []
    tide_traj = list(tidal)
    e_tide: list[float] = []
    e_tide_full: list[float] = []
    matched = config_from_dict(deep_merge(mission_config(m), matched_config(m, cfg)))
    navd = iter(navd_core(g, matched, math.sqrt(model.r_var)))
    e_ekf: list[float] = []
    e_full: list[float] = []
    e_navd: list[float] = []
    in_full: list[bool] = []
    in_navd: list[bool] = []
    bvar: list[float] = []
    traj = list(lin)
    for i, nd in enumerate(g.nodes):
        if not nd.scored:
            continue
        xf, P = _solve_to(model, traj, i)
        truth = g.truth_x[nd.k, 0:2]
        de, df = lin[i][0:2] - truth, xf[0:2] - truth
        ne, cov = next(navd)
        dn = ne - truth
        e_ekf.append(float(de @ de))
        if tide_model is not None:
            dw = tidal[i][0:2] - truth
            e_tide.append(float(dw @ dw))
            dw = _solve_to(tide_model, tide_traj, i)[0][0:2] - truth
            e_tide_full.append(float(dw @ dw))
        e_full.append(float(df @ df))
        e_navd.append(float(dn @ dn))
        in_full.append(_inside95(df, P[0:2, 0:2]))
        in_navd.append(_inside95(dn, cov))
        bvar.append(g.bound_var[nd.k])
    return Scored(
        seed,
        dr.cls,
        dr.kind,
        len(bvar),
        math.sqrt(statistics.fmean(bvar)),
        math.sqrt(statistics.fmean(e_ekf)),
        math.sqrt(statistics.fmean(e_full)),
        statistics.fmean(in_full),
        math.sqrt(statistics.fmean(e_navd)),
        statistics.fmean(in_navd),
        time.perf_counter() - t0,
        math.sqrt(statistics.fmean(e_tide)) if e_tide else math.nan,
        math.sqrt(statistics.fmean(e_tide_full)) if e_tide_full else math.nan,
    )


def _rms(xs: Sequence[float]) -> float:
    return math.sqrt(statistics.fmean([x * x for x in xs]))


def _ratio(rs: Sequence[Scored], of: Callable[[Scored], float]) -> float:
    return _rms([of(r) for r in rs]) / _rms([r.bound_m for r in rs])


def _interval(rs: Sequence[Scored], of: Callable[[Scored], float]) -> str:
    """The ratio with its 90 % bootstrap interval over the runs (a mission's error is a few
    draws of slow errors, so a class's ratio is uncertain by tens of percent)."""
    rng = random.Random(0)
    boot = sorted(_ratio(rng.choices(rs, k=len(rs)), of) for _ in range(_BOOTSTRAP))
    lo, hi = boot[_BOOTSTRAP // 20], boot[_BOOTSTRAP - 1 - _BOOTSTRAP // 20]
    return f"{_ratio(rs, of):.2f} ({lo:.2f}-{hi:.2f})"


def table(rows: Sequence[Scored]) -> str:
    """Per class (the nets apart), each estimator's RMS over the runs over the bound's."""
    groups: dict[str, list[Scored]] = {}
    for r in sorted(rows, key=lambda r: (r.kind != "beacon", r.kind, r.cls)):
        name = f"class {r.cls}" if r.kind == "beacon" else f"{r.kind} net"
        groups.setdefault(name, []).append(r)
    groups["**all**"] = list(rows)
    tides = any(math.isfinite(r.tide_m) for r in rows)
    out = [
        "| class | runs | bound | EKF / bound | full information / bound | its in95 "
        "| navd / bound | navd's in95 |" + (" runs with it | their EKF / bound | "
        "EKF with the tide's form / bound | full information with it / bound |"
        if tides else ""),
        "|---|---|---|---|---|---|---|---|" + ("---|---|---|---|" if tides else ""),
    ]
    for name, rs in groups.items():
        line = (
            f"| {name} | {len(rs)} | {statistics.fmean(r.bound_m for r in rs):.1f} | "
            f"{_ratio(rs, lambda r: r.ekf_m):.2f} | {_interval(rs, lambda r: r.full_m)} | "
            f"{statistics.fmean(r.full_in95 for r in rs):.2f} | "
            f"{_interval(rs, lambda r: r.navd_m)} | "
            f"{statistics.fmean(r.navd_in95 for r in rs):.2f} |"
        )
        tidal = [r for r in rs if math.isfinite(r.tide_m)]
        if tides and tidal:
            line += (
                f" {len(tidal)} | {_ratio(tidal, lambda r: r.ekf_m):.2f} | "
                f"{_interval(tidal, lambda r: r.tide_m)} | "
                f"{_interval(tidal, lambda r: r.tide_full_m)} |"
            )
        elif tides:
            line += " 0 | - | - | - |"
        out.append(line)
    return "\n".join(out)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=120)
    p.add_argument("--jobs", type=int, default=default_jobs())
    p.add_argument("--only", choices=list(CLASSES), help="of seeds 1..--missions, this class's")
    p.add_argument(
        "--draws", type=int, default=2, help="draws of the noise along each mission's truth"
    )
    p.add_argument(
        "--walk-current",
        action="store_true",
        help="each mission's current drawn from the bound's own random walk instead of the "
        "truth's (a tidal stream turns smoothly, which such a walk seldom does)",
    )
    tide = p.add_mutually_exclusive_group()
    tide.add_argument(
        "--tide",
        type=float,
        metavar="FACTOR",
        help="fly, on each mission with a tide, an EKF and full information that know the "
        "tide's form too: each "
        "constituent's prior std FACTOR times the mission's amplitude over sqrt 2",
    )
    tide.add_argument(
        "--tide-std",
        type=float,
        metavar="MPS",
        help="the same, each constituent's prior std MPS whatever the mission (a site's "
        "strongest tide over sqrt 2)",
    )
    p.add_argument(
        "--tide-everywhere",
        action="store_true",
        help="with --tide-std, fly the tide's form on every mission, those whose water has "
        "no tide too (a prior for water whose tide nobody predicted: what it costs there)",
    )
    p.add_argument(
        "--tide-walk",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="with the tide's form, the mean current keeps SHARE of the bound's walk "
        "(default 0: the Monte Carlo's water changes only by its tide)",
    )
    p.add_argument("--write", help="BENCHMARKS.md to update")
    args = p.parse_args()
    if args.tide_everywhere and args.tide_std is None:
        p.error("--tide-everywhere needs --tide-std (a mission without a tide has no amplitude)")
    seeds = list(range(1, args.missions + 1))
    if args.only:
        seeds = [s for s in seeds if draw(s).cls == args.only]
    runs = [
        (s, j, args.walk_current, args.tide, args.tide_std, args.tide_everywhere, args.tide_walk)
        for s in seeds
        for j in range(args.draws)
    ]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as ex:
        rows = [r for r in ex.map(run_one, *zip(*runs, strict=True)) if r is not None]
    took = (time.perf_counter() - t0) / 60.0
    for r in rows:
        print(
            f"seed {r.seed:4d} {r.cls:14s} {r.kind:7s} bound {r.bound_m:7.1f} "
            f"ekf {r.ekf_m:7.1f} full {r.full_m:7.1f} ({r.full_in95:.2f}) "
            f"navd {r.navd_m:7.1f} ({r.navd_in95:.2f}) tide {r.tide_m:7.1f} "
            f"{r.tide_full_m:7.1f} {r.seconds:.0f} s"
        )
    flags = (
        (f" --only {args.only}" if args.only else "")
        + (" --walk-current" if args.walk_current else "")
        + (f" --tide {args.tide:g}" if args.tide is not None else "")
        + (f" --tide-std {args.tide_std:g}" if args.tide_std is not None else "")
        + (" --tide-everywhere" if args.tide_everywhere else "")
        + (f" --tide-walk {args.tide_walk:g}" if args.tide_walk else "")
    )
    body = (
        f"`python -m bench.attainable --missions {args.missions}{flags} --draws {args.draws}`\n\n"
        f"{len(rows)} runs: the missions of seeds 1..{args.missions} (bench/robustness.py's "
        f"draws{', ' + args.only + ' only' if args.only else ''}) with {args.draws} draws of the "
        "bound's own noise along its truth (bench/attainable.py). *EKF*, *full information*: "
        "estimators that know the bound's model, the second solving the whole past again at "
        "each instant; *navd*: navd's default mode configured with the bound's model "
        "(`--matched-noise`), on the same measurements. RMS over the runs over the bound's; "
        "in brackets its 90 % bootstrap interval over the runs; *in95*: how often the truth lay "
        "in the estimator's own 95 % ellipse."
        + (
            " *with the tide's form*: the EKF, and the full-information estimate, with the "
            "tide's four constituents as states (`Tide` in bench/attainable.py), on the runs "
            + ("of every mission" if args.tide_everywhere else "whose mission has a tide")
            + ", beside the EKF with the walk on the same runs"
            + (
                f"; the mean current keeps {args.tide_walk:g} of the walk."
                if args.tide_walk
                else "."
            )
            if args.tide is not None or args.tide_std is not None
            else ""
        )
        + f"\n\n{table(rows)}\n\nRan in {took:.1f} min on {args.jobs} worker processes."
    )
    print(body)
    if args.write:
        write_section(
            Path(args.write),
            "bench-attainable",
            "What the bound's own model lets an estimator reach (`make bench-attainable`)",
            body,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
