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
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

from navd.filter import estimate
from navd.filter.common import principal_axes
from navd.filter.navfusion import Fusion
from navd.filter.navresume import Resuming
from navd.records import (
    BEACON_NAME,
    MAX_BEACONS,
    MAX_LATE_S,
    Attitude,
    Clock,
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
from navd.schema import Estimate, Output, finite
from navd.settings import Beacon

_TICK_SLACK_S = 1e-6  # far below a tick (0.01 s at 100 Hz), far above float rounding
#: a clock this far off moves the tidal prediction by at most 2 pi 60 / 44714 (0.8 %) of
#: its speed; closer, the clock it has stands (a receiver's time lags its fix a little)
CLOCK_TOLERANCE_S = 60.0
#: two clocks the computer gave this close are one (a log header's time is rounded)
SAME_CLOCK_S = 1.0


class Navigator(Fusion, Resuming):
    """Time and dispatch: each record to its handler after the ticks before it, each
    tick's estimate (the parts it runs are in navd/filter/navparts.py)."""

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
        if isinstance(rec, Clock):
            self._on_clock(rec)  # a time, not a measurement: no step of the filter
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

    def set_clock(self, utc_at_zero: float | None) -> None:
        """UTC seconds since the Unix epoch at the records' t = 0 (a log's header, the
        daemon's clock), which the crew's tidal prediction is given in
        (navd/filter/tide.py); None, or a value that is not finite: not known, and the
        prediction waits."""
        ok = utc_at_zero is not None and math.isfinite(utc_at_zero)
        given = utc_at_zero if ok else None
        before, self.computer_clock = self.computer_clock, given
        if self.tide is None:
            return
        same = given is not None and before is not None and abs(given - before) < SAME_CLOCK_S
        if same and self.clock_from_gps:
            # the same computer's clock again (a rotated log's next file, the same
            # daemon): what the GPS receiver said of it stands, as it did in the daemon
            return
        self.tide.offset_s = given
        self.clock_from_gps = False

    def _on_clock(self, rec: Clock) -> None:
        """The GPS receiver's UTC: the tidal prediction's clock, where the one it had
        (the computer's, the log's header) is unknown or off by more than
        ``CLOCK_TOLERANCE_S``.  The receiver's is the one to trust: a board without a
        real-time clock, at sea without a network, may start hours off."""
        tide = self.tide
        if tide is None:
            return
        at_zero = rec.utc_s - rec.t
        if tide.offset_s is None:
            self.counters["tide_clock_from_gps"] += 1
        elif abs(tide.offset_s - at_zero) > CLOCK_TOLERANCE_S:
            self.counters["tide_clock_corrected"] += 1
        else:
            return
        tide.offset_s = at_zero
        self.clock_from_gps = True

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
        if not self._at_surface():
            self.gps.antenna_under()

    def _on_pressure(self, rec: Pressure) -> None:
        self.depth.pressure(rec.t, rec.bar, surfaced=self.gps.fresh(rec.t))
        if not self._at_surface():
            self.gps.antenna_under()

    def _on_velocity(self, rec: Velocity) -> None:
        # DVL dead reckoning runs beside the range filter, with its predicted error
        self._dvl_seen = True
        if not self.dvl.velocity(rec.t, rec.u, rec.v, rec.w):
            self.counters["dvl_spikes"] += 1

    # -- outputs -----------------------------------------------------------------------
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

__all__ = ["Navigator"]
