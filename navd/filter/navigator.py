"""The navigator: records in time order in, estimates at the filter rate out.

It is pure: no clock, no I/O.  The daemon feeds it records stamped with their
arrival time, ``navd replay`` feeds it a log; both get the same outputs for the
same records.  Inputs (heading, RPM, depth) are held from their last sample
(zero-order hold).  The filter steps to every tick and to the exact time of every
measurement (a fix, a range, a DVL velocity); over each step it takes the
time-weighted mean of the inputs held during it (navd/filter/inputs.py), so when an
input falls between ticks changes the answer only by rounding.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from navd.filter import estimate
from navd.filter.bank import CalibrationBank
from navd.filter.common import (
    NavFilter,
    principal_axes,
)
from navd.filter.deadreckoning import DeadReckoner
from navd.filter.depth import DepthGauge
from navd.filter.dvl import DvlDeadReckoner, DvlSpec
from navd.filter.ekf import RangeEKF
from navd.filter.gpsfix import DEPTH_TRUST_S, GpsFixes, GpsGate
from navd.filter.inputs import HeldInputs
from navd.filter.integrity import Integrity
from navd.filter.ranging import Ranging
from navd.filter.smoothing import Smoothing
from navd.filter.thesis import ThesisEKF
from navd.filter.vlblmode import VlblMode
from navd.records import (
    BEACON_NAME,
    MAX_BEACONS,
    MAX_LATE_S,
    Attitude,
    Depth,
    Gps,
    Heading,
    Pressure,
    Range,
    Record,
    Reset,
    Resume,
    Rpm,
    SetBeacon,
    Tick,
    TravelTime,
    Velocity,
    implausible,
)
from navd.schema import Advisory, Estimate, Output, RangeDecision, finite
from navd.settings import Beacon, Config

_TICK_SLACK_S = 1e-6  # far below a tick (0.01 s at 100 Hz), far above float rounding


def make_filter(cfg: Config) -> NavFilter:
    nav = cfg.navigation
    nz = nav.noise
    if nav.filter == "vlbl":
        return VlblMode()
    if nav.filter == "thesis":
        return ThesisEKF(
            nz.position_init_std_m,
            nz.current_init_std_mps,
            nz.thesis_position_walk_m_per_sqrt_s,
            nz.thesis_current_walk_mps_per_sqrt_s,
        )
    g = nav.gate
    return CalibrationBank(
        RangeEKF(nz, g.chi2, g.chi2_long, g.reacquire_after, nav.max_current_mps)
    )


class Navigator:
    def __init__(self, cfg: Config, keep_history: bool = False) -> None:
        self.cfg = cfg
        self.nav = cfg.navigation
        self.counters: Counter[str] = Counter()
        # the RTS smoother's record of the run, kept only when asked for
        self.smoothing: Smoothing | None = Smoothing() if keep_history else None
        self._fresh()

    def _fresh(self) -> None:
        """Everything a new process knows before its first record (counters and the
        smoother's finished segments are the run's, and stay)."""
        cfg = self.cfg
        nav = self.nav
        self.filter: NavFilter = make_filter(cfg)
        if self.smoothing is not None:
            self.smoothing.start(self.filter)
        self.dr = DeadReckoner()
        d = nav.dvl
        self.dvl = DvlDeadReckoner(
            DvlSpec(
                d.velocity_error_frac,
                d.attitude_error_deg,
                d.max_accel_mps2,
                d.max_rejections,
                d.error_limit_m,
            ),
            math.radians(nav.magnetic_declination_deg),
        )
        self._dvl_seen = False
        self.ranging = Ranging(cfg, self.counters)
        self.tick_dt = 1.0 / nav.rate_hz
        ig = nav.integrity
        self.integrity = Integrity(
            ig.window, ig.degraded_std_m, ig.lost_std_m, ig.degraded_refused, ig.lost_refused
        )
        self.warnings: list[str] = list(self.ranging.sound.warnings())

        self._tick_k: int | None = None
        self._t_filter: float | None = None
        self.inputs = HeldInputs(nav)
        self.depth = DepthGauge(cfg.site)
        self.gps = GpsFixes(nav, cfg.site)
        self.gps_gate = GpsGate(nav.gate.gps_chi2, nav.gate.gps_agree)

    # -- public ------------------------------------------------------------------------
    def feed(self, rec: Record, checked: bool = False) -> list[Output]:
        """Consume one record; return the outputs (ticks before it, its decision).

        ``checked``: the caller has put ``rec`` through :func:`implausible` already
        (the log reader has), so it is not tested twice.
        """
        if isinstance(rec, Tick):
            if self._tick_k is None:
                # the first tick since a start: the daemon counted from this one (its
                # k * dt), not from the one after it, which the slack below would give
                self._tick_k = round(rec.t / self.tick_dt)
            # the log rounds a tick's time to 1 ns; k * dt may lie a hair above it
            return self.advance(rec.t + _TICK_SLACK_S)
        if isinstance(rec, Resume):
            # the daemon started again: no ticks were taken while it was down
            if implausible(rec) is None:
                self._on_resume(rec)
            else:
                self.counters["skipped_implausible"] += 1
            return []
        if not checked and implausible(rec) is not None:
            # the decoders and the log reader refuse these already; records made by
            # other callers get the same test, so no value can blow up a step
            self.counters["skipped_implausible"] += 1
            return []
        t = rec.t
        if self._t_filter is not None and t < self._t_filter:
            if isinstance(rec, Range | TravelTime) and self._t_filter - t <= MAX_LATE_S:
                # completed after records that arrived behind its first byte: fuse it
                # at its own time (the filter's round-trip geometry looks back to t)
                self.counters["ranges_late"] += 1
                return [self._on_range(rec)]
            self.counters["skipped_out_of_order"] += 1
            return []
        if self._t_filter is not None and t - self._t_filter > self.nav.max_gap_s:
            # Nothing heard for that long: the old estimate means nothing, and filling
            # the gap with ticks could mean millions of them.  Start over at the next fix.
            self.restart("after_gap")
        out = self._ticks_until(t, inclusive=False)
        if type(rec) in _HELD:
            self._hold_to(t)
        else:
            self._propagate_to(t)
        handler = _HANDLERS.get(type(rec))
        if handler is None:  # pragma: no cover - every record type has a handler
            self.counters["skipped_unknown_record"] += 1
            return out
        decision = handler(self, rec)
        if decision is not None:
            out.append(decision)
        return out

    def restart(self, reason: str) -> None:
        """Forget the estimate and start again at the next GPS fix."""
        self.counters[f"restarts_{reason}"] += 1
        self.filter = make_filter(self.cfg)
        if self.smoothing is not None:
            self.smoothing.start(self.filter)
        self.integrity.clear()
        self.ranging.observability.clear()
        self.dr = DeadReckoner()
        self._tick_k = None
        self._t_filter = None
        self.gps.forget()
        self.gps_gate.clear()

    def _on_reset(self, rec: Reset) -> None:
        self.restart("command")

    def _on_set_beacon(self, rec: SetBeacon) -> None:
        """Use this fixed position for the beacon where its replies carry none.

        Only the position changes: the configured turnaround time and position error
        of that beacon still hold.
        """
        table = self.ranging.beacons.beacons
        if not BEACON_NAME.fullmatch(rec.beacon):
            self.counters["beacon_commands_refused_name"] += 1
            return
        if rec.beacon not in table and len(table) >= MAX_BEACONS:
            # the daemon refuses the command; a log of other origin gets the same limit
            self.counters["beacon_commands_refused_limit"] += 1
            return
        known = table.get(rec.beacon, Beacon())
        table[rec.beacon] = replace(known, lat=rec.lat, lon=rec.lon, depth=rec.depth)

    def snapshot(self) -> dict[str, Any] | None:
        """What a restart needs to resume navigating (None: nothing to resume yet): the
        filter's state and covariance, the depth gauge's zero, the water's height."""
        f = self.filter
        if not f.initialised:
            return None
        x = np.asarray(f.x, dtype=float)
        return {
            "mode": self.cfg.navigation.filter,
            "x": x.tolist(),
            "P": np.asarray(f.P, dtype=float).ravel().tolist(),
            "surface_bar": self.depth.zero_bar,
            "surface_alt": self.surface_altitude,
            "depth_m": self.depth.m,
            "lat": math.degrees(float(x[0])),
            "lon": math.degrees(float(x[1])),
        }

    def _on_resume(self, rec: Resume) -> None:
        """Navigate on from a checkpoint: navd restarted (a crash, the watchdog) while
        the vehicle was away from GPS.  Its position covariance grows with the time
        the daemon was down, and integrity is degraded until ranges confirm it."""
        n = len(rec.x)
        # a new process: what the one before knew is gone (a replay of its log goes on
        # from here as the daemon did)
        self._fresh()
        if rec.mode != self.cfg.navigation.filter or n != len(np.asarray(self.filter.x)):
            self.counters["resume_refused_mode"] += 1
            return
        if len(rec.P) != n * n:
            self.counters["resume_refused_covariance"] += 1
            return
        x = np.array(rec.x, dtype=float)
        P = np.array(rec.P, dtype=float).reshape(n, n)
        if not np.all(np.linalg.eigvalsh(0.5 * (P + P.T)) >= -1e-9):
            self.counters["resume_refused_covariance"] += 1
            return
        grow = (self.cfg.checkpoint.drift_mps * rec.age_s) ** 2
        self.filter.initialise(float(x[0]), float(x[1]), 1.0, rec.t)
        self.filter.restore(x, P, grow)
        self._t_filter = rec.t
        self.dr.reset(float(x[0]), float(x[1]))
        if rec.surface_bar is not None:
            self.depth.zero_at(rec.surface_bar)
        if rec.surface_alt is not None:
            self.gps.seed_altitude(rec.surface_alt)
        if rec.depth_m is not None:
            self.depth.depth(rec.t, rec.depth_m)
        self.integrity.resumed(
            f"resumed from a checkpoint {rec.age_s:.0f} s old, not yet confirmed by ranges"
        )
        self.counters["resumed"] += 1

    def advance(self, t: float) -> list[Output]:
        """Run the ticks up to and including ``t`` (the daemon's clock, a tick of its log,
        or the end of a log)."""
        if self._t_filter is not None and t - self._t_filter > self.nav.max_gap_s:
            # as for a record after a gap: a tick far ahead is no reason to step the
            # filter through every 0.1 s of it
            self.restart("after_gap")
        return self._ticks_until(t, inclusive=True)

    def smoothed(self) -> Iterator[Estimate]:
        """Estimates re-written by the Rauch-Tung-Striebel smoother over the whole run,
        one at a time (nothing, unless made with ``keep_history``)."""
        if self.smoothing is not None:
            yield from self.smoothing.smoothed()

    @property
    def surface_altitude(self) -> float:
        return self.gps.surface_altitude

    # -- time --------------------------------------------------------------------------
    def _ticks_until(self, t: float, inclusive: bool) -> list[Output]:
        if self._tick_k is None:
            self._tick_k = math.ceil(t / self.tick_dt - 1e-9)
        out: list[Output] = []
        while True:
            tk = self._tick_k * self.tick_dt
            if tk > t or (tk == t and not inclusive):
                break
            self._propagate_to(tk)
            est = self._estimate_record(tk)
            if est is not None:
                out.append(est)
            self._tick_k += 1
        return out

    def _hold_to(self, t: float) -> None:
        """An input is about to change at ``t``: keep what was held until then for the
        next step (navd.filter.inputs), instead of stepping the filter to ``t``."""
        if self._t_filter is None or t <= self._t_filter:
            return
        self.inputs.carry(self._t_filter, t)
        if self._dvl_seen:
            # the DVL's track turns with the attitude: it moves to t before it changes
            self.dvl.advance(t, self.surface_altitude - self.depth.m)

    def _propagate_to(self, t: float) -> None:
        if self._t_filter is None:
            self._t_filter = t
            return
        remaining = t - self._t_filter
        if remaining <= 0.0:
            if not self.filter.initialised:
                self._t_filter = t
            return
        heading, speed = self.inputs.over(self._t_filter, t)
        # the virtual net's relative track: needs no absolute position
        self.ranging.net.move(speed * remaining, heading)
        if not self.filter.initialised:
            self._t_filter = t
            return
        hd = self.surface_altitude - self.depth.m
        # Long gaps (a log with a hole) are crossed in steps of one tick.
        n = max(1, math.ceil(remaining / self.tick_dt - 1e-9))
        step = remaining / n
        for i in range(1, n + 1):
            self.filter.predict(self._t_filter + i * step, step, heading, speed, hd)
            self.dr.step(step, heading, speed, hd)
        if self._dvl_seen:
            self.dvl.advance(t, hd)
        self._t_filter = t

    # -- inputs ------------------------------------------------------------------------
    def _on_heading(self, rec: Heading) -> None:
        self.inputs.heading(rec)

    def _on_attitude(self, rec: Attitude) -> None:
        yaw = self.inputs.attitude(rec)
        self.dvl.attitude(rec.roll_deg, rec.pitch_deg, yaw)

    def _on_rpm(self, rec: Rpm) -> None:
        self.inputs.motor(rec)

    def _on_depth(self, rec: Depth) -> None:
        self.depth.depth(rec.t, rec.m)

    def _on_pressure(self, rec: Pressure) -> None:
        self.depth.pressure(rec.t, rec.bar, surfaced=self.gps.fresh(rec.t))

    def _on_velocity(self, rec: Velocity) -> None:
        # DVL dead reckoning runs beside the range filter, with its predicted error
        self._dvl_seen = True
        if not self.dvl.velocity(rec.t, rec.u, rec.v, rec.w):
            self.counters["dvl_spikes"] += 1

    def _at_surface(self) -> bool:
        return self.depth.m < self.nav.surface_depth_m

    def _on_gps(self, rec: Gps) -> None:
        std, said = self.gps.judge(rec, self._at_surface(), self.depth.t)
        for c in said:
            self.counters[c] += 1
        if std is None or rec.lat is None or rec.lon is None:
            return
        lat, lon = math.radians(rec.lat), math.radians(rec.lon)
        hd = self.surface_altitude - self.depth.m
        if self.filter.initialised:
            # the first fix of a mission, and the first after a reset, are not gated
            verdict = self.gps_gate.judge(self.filter.estimate(), lat, lon, std, rec.t)
            if verdict == "refuse":
                self.counters["gps_refused_gate"] += 1
                self.integrity.fix_refused()
                return
            if verdict == "take":
                # several fixes agree with each other and not with the estimate: it had
                # drifted beyond its covariance, and they are the position
                self.counters["gps_reacquired"] += 1
                self.restart("gps_disagrees")
                self.gps.t_last = rec.t  # this fix counts: it is the one restarting it
        if not self.filter.initialised:
            self.filter.initialise(lat, lon, std, rec.t)
            self._t_filter = rec.t
        else:
            self.filter.gps_update(lat, lon, std, hd)
        self.integrity.clear()
        self.dr.reset(lat, lon)
        self.dvl.reset(lat, lon, rec.t)
        self.counters["gps_fused"] += 1

    def _on_range(self, rec: Range | TravelTime) -> RangeDecision:
        return self.ranging.decide(
            rec,
            self.filter,
            self.integrity,
            self.dr,
            depth_m=self.depth.m,
            surface_alt=self.surface_altitude,
            gps_fresh=self.gps.fresh(rec.t),
            gps_seen=self.gps.t_last is not None,
        )

    # -- outputs -----------------------------------------------------------------------
    def advisory(self, t: float, heading_deg: float | None) -> Advisory:
        """How well the recent ranges fix each direction (navd/filter/advisory.py)."""
        return self.ranging.observability.assess(t, heading_deg)

    def input_ages(self, t: float) -> dict[str, float | None]:
        """Seconds since the last heading, RPM and depth (None: never seen)."""
        i = self.inputs
        ages = {"heading": i.t_heading, "rpm": i.t_rpm, "depth": self.depth.t}
        return {k: (t - v if math.isfinite(v) else None) for k, v in ages.items()}

    def mode(self, t: float) -> str:
        depth_stale = t - self.depth.t > DEPTH_TRUST_S
        if not self._at_surface() and not (depth_stale and self.gps.fresh(t)):
            return "submerged"
        if self.gps.warmed_up(t):
            return "surface"
        return "surfacing"

    def _estimate_record(self, t: float) -> Estimate | None:
        if not self.filter.initialised:
            return None
        state = self.filter.estimate()
        std_max = math.sqrt(max(0.0, principal_axes(state.var_n, state.var_e, state.cov_ne)[0]))
        integrity = self.integrity.assess(std_max)
        heading, speed = self.inputs.heading_speed()
        stale = self.inputs.stale(t)
        if stale:
            self.counters["ticks_with_stale_input"] += 1
        est = estimate.build(
            t,
            state,
            depth=self.depth.m,
            mode=self.mode(t),
            integrity=integrity,
            integrity_reason=self.integrity.reason,
            corrections=self.filter.corrections(),
            heading=heading,
            speed=speed,
            dr=self.dr,
            net=self.ranging.net,
            dvl=self.dvl if self._dvl_seen else None,
            stale=stale,
        )
        if not finite(est):
            # Never publish a NaN: say so and skip the tick.
            self.counters["estimates_not_finite"] += 1
            return None
        if self.smoothing is not None:
            self.smoothing.tick(est)
        return est


# Records that only change a held input: the filter steps at the next tick or
# measurement with what was held in between (navd.filter.inputs).
_HELD = frozenset({Heading, Attitude, Rpm, Depth, Pressure})

_HANDLERS: dict[type, Any] = {
    Heading: Navigator._on_heading,
    Attitude: Navigator._on_attitude,
    Rpm: Navigator._on_rpm,
    Depth: Navigator._on_depth,
    Pressure: Navigator._on_pressure,
    Gps: Navigator._on_gps,
    Range: Navigator._on_range,
    TravelTime: Navigator._on_range,
    Velocity: Navigator._on_velocity,
    Reset: Navigator._on_reset,
    SetBeacon: Navigator._on_set_beacon,
}

__all__ = ["Navigator", "make_filter"]
