"""``navd run``: the daemon the vehicle runs.

The orchestration of the device objects (navd/daemon/devices/: each owns its port's
open sequence, polls and records), a 10 Hz filter tick on absolute monotonic
deadlines, a 1 Hz health task, zenoh publishing and the crash-safe log.  Every
measurement is stamped with the monotonic time its bytes arrived and fed to the same
:class:`~navd.filter.Navigator` that ``navd replay`` runs, so the log replays to the
same estimates.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import replace

from navd.config import log_dir
from navd.daemon import pace
from navd.daemon.checkpoint import (
    Checkpoints,
    checkpoint_dir,
    config_digest,
    keep_writing,
    resume,
)
from navd.daemon.devices import Device, make_devices, wait_open
from navd.daemon.health import TickTimes, Vitals
from navd.daemon.publish import (
    BeaconCommand,
    Command,
    Outlet,
    OutletFactory,
    ResetCommand,
    open_with_retry,
)
from navd.daemon.resets import ResetRule
from navd.daemon.sdnotify import Notifier
from navd.daemon.status import every_second, health_of
from navd.drivers.codec import Decoder, DecodeStats
from navd.filter import Navigator
from navd.formats.log import RecordLog
from navd.formats.mlog import log_epoch
from navd.records import MAX_BEACONS, Record, Reset, SetBeacon
from navd.schema import Estimate, Health, Output, RangeDecision
from navd.settings import Config

log = logging.getLogger("navd")
LOG_FLUSH_S = 0.25  # kill -9 loses at most this much of the log
STOP_TIMEOUT_S = 10.0  # inside the unit's TimeoutStopSec (15 s): the log is closed in time


class _Logged:
    """A decoder wrapper that logs the raw bytes before decoding them."""

    def __init__(self, name: str, inner: Decoder, rlog: RecordLog) -> None:
        self.name, self.inner, self.rlog = name, inner, rlog
        self.stats: DecodeStats = inner.stats  # the same counters, not a copy

    def feed(self, data: bytes, t: float) -> list[object]:
        self.rlog.raw_bytes(t, self.name, data)
        return self.inner.feed(data, t)

    def reset(self) -> None:
        self.inner.reset()

    def refeed(self, data: bytes, t: float) -> list[object]:
        """Bytes already logged, fed again after a decoder fault (not logged twice)."""
        return self.inner.feed(data, t)


class Daemon:
    def __init__(
        self,
        cfg: Config,
        clock: Callable[[], float] = time.monotonic,
        notifier: Notifier | None = None,
        publisher_factory: OutletFactory | None = None,
    ) -> None:
        self.cfg = cfg
        self.clock = clock
        self.notifier = notifier or Notifier()
        self.nav = Navigator(cfg)
        # records are stamped with ``clock``; the tidal prediction is in UTC: the system
        # clock now, then exactly as each log file's header gives it, as a replay of the
        # file reads it (navd.formats.mlog.log_epoch)
        self.nav.set_clock(time.time() - clock())
        lc = cfg.log
        self.rlog = RecordLog(
            log_dir(cfg, os.environ),
            lc.rotate_mb,
            lc.raw_bytes,
            lc.raw_budget_bytes_per_s,
            lc.keep_mb,
        )
        self.rlog.on_header = lambda header: self.nav.set_clock(log_epoch(dict(header)))
        self.publisher_factory = publisher_factory
        self.pub: Outlet | None = None
        where = checkpoint_dir(cfg, os.environ)
        self.checkpoints = (
            Checkpoints(where, cfg.vehicle.name, config_digest(cfg)) if where is not None else None
        )
        self.resumed: dict[str, object] | None = None  # what this run resumed from, if anything
        self.vitals = Vitals(
            cfg.navigation.rate_hz,
            cfg.devices.modem.ping_interval_s,
            max(cfg.navigation.stale_input_s, 2.0),
            t_started=clock(),
        )
        self.devices: dict[str, Device] = make_devices(cfg, self)
        self.dt = 1.0 / cfg.navigation.rate_hz
        self.times = TickTimes()
        self.fused = 0  # range decisions the filter made: every range should get one
        self.latest: Estimate | None = None
        self._last_watchdog = -math.inf
        # exceptions of the navigator, by kind: caught so one bad record cannot stop
        # the daemon, logged once, shown in health
        self.internal_errors: dict[str, int] = {}
        self.t_internal_error: float | None = None
        self.zenoh_error = ""  # why the zenoh session is not open, while it is not
        self.resets = ResetRule()

    # -- records in ------------------------------------------------------------------
    def feed(self, rec: Record) -> None:
        """A measurement, stamped with its arrival, to the log and the filter."""
        self.rlog.record(rec)
        try:
            outs = self.nav.feed(rec)
        except Exception as exc:
            self._navigator_failed(exc)
            return
        self._outputs(outs)

    def logged(self, name: str, decoder: Decoder) -> _Logged:
        """A device's decoder, with the raw bytes it is fed kept in the log first."""
        return _Logged(name, decoder, self.rlog)

    def _navigator_failed(self, exc: Exception) -> None:
        # The core is meant to be total (tests/test_navigator_total.py); if it still
        # raises, its state may be half updated, so it starts again from the next fix.
        kind = f"navigator: {exc.__class__.__name__}"
        n = self.internal_errors.get(kind, 0)
        self.internal_errors[kind] = n + 1
        self.t_internal_error = self.clock()
        if n == 0:
            log.error("%s raised; restarting the filter (counted in health)", kind, exc_info=exc)
        self.nav.restart("internal_error")

    def _outputs(self, outs: list[Output]) -> None:
        for o in outs:
            self.rlog.output(o)
            match o:
                case Estimate():
                    self._publish_estimate(o)
                case RangeDecision():
                    self.fused += 1
                    if o.accepted:
                        self.vitals.range_accepted(self.clock())
                    if self.pub is not None:
                        self.pub.put(o)

    def _publish_estimate(self, est: Estimate) -> None:
        # the log keeps the filter's time alone; zenoh's readers get the system's UTC too
        utc = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
        self.latest = replace(est, t_utc=utc)
        self.vitals.estimate(self.clock())
        if self.pub is not None:
            self.pub.put(self.latest)
        self.times.publish.append(self.clock() - est.t)

    # -- commands from the autopilot (zenoh thread -> loop) -----------------------------
    def on_command(self, cmd: Command) -> str | None:
        """Carry out a validated command, or say why it is refused (None: done).

        It is fed like a measurement, so the log keeps it and replay redoes it.
        """
        match cmd:
            case ResetCommand():
                return self._reset(cmd.force)
            case BeaconCommand():
                known = self.nav.ranging.beacons.beacons
                if cmd.name not in known and len(known) >= MAX_BEACONS:
                    return f"at most {MAX_BEACONS} beacons"
                self.feed(SetBeacon(self.clock(), cmd.name, cmd.lat, cmd.lon, cmd.depth))
        return None

    def _reset(self, force: bool) -> str | None:
        t = self.clock()
        refused = self.resets.allow(t, self.nav.mode(t) == "submerged", force)
        if refused is not None:
            return refused
        self.feed(Reset(t))
        if self.pub is not None:
            self.pub.forget_latest()
        return None

    # -- tasks -------------------------------------------------------------------------
    async def _ticker(self) -> None:
        dt_ = self.dt
        k = math.ceil(self.clock() / dt_)
        while True:
            deadline = k * dt_
            delay = deadline - self.clock()
            if delay > 0:
                await asyncio.sleep(delay)
            now = self.clock()
            late = now - deadline
            self.times.lateness.append(late)
            if late > dt_:
                self.times.overruns += 1
                k = math.floor(now / dt_)  # catch up: the navigator emits every missed tick
            for dev in self.devices.values():
                dev.on_tick(now)
            try:
                self._outputs(self.nav.advance(k * dt_))
            except Exception as exc:
                self._navigator_failed(exc)
            self.times.ticks += 1
            if (
                self.notifier.watchdog_s
                and now - self._last_watchdog >= self.notifier.watchdog_s / 2
                and self.vitals.navigating(now, self.nav.filter.initialised)
            ):
                # from the loop itself, and only while estimates come out: systemd
                # restarts a daemon whose loop hangs or whose navigation is dead
                self.notifier.watchdog()
                self._last_watchdog = now
            k += 1

    async def _zenoh(self) -> None:
        if self.publisher_factory is None:
            return
        self.pub = await open_with_retry(
            self.publisher_factory, self.on_command, lambda why: setattr(self, "zenoh_error", why)
        )

    async def _log_flusher(self) -> None:
        last_sync = self.clock()
        while True:
            await pace.sleep_to_next(LOG_FLUSH_S, self.clock)
            if self.clock() - last_sync >= self.cfg.log.fsync_s:
                self.rlog.sync()
                last_sync = self.clock()
            else:
                self.rlog.flush()

    def health(self) -> Health:
        return health_of(self, self.clock())

    async def run(self, stop: asyncio.Event) -> None:
        loop = asyncio.get_running_loop()
        if self.checkpoints is not None:
            self.resumed = resume(
                self.checkpoints,
                self.cfg.checkpoint.max_age_s,
                self.clock(),
                self.feed,
                self.nav.counters,
            )
        for dev in self.devices.values():
            dev.transport.start()
        loops = [self._zenoh(), self._ticker(), every_second(self), self._log_flusher()]
        if self.checkpoints is not None:
            every = self.cfg.checkpoint.every_s
            loops.append(keep_writing(self.checkpoints, every, self.nav.snapshot))
        tasks = [loop.create_task(c) for c in loops]
        tasks += [loop.create_task(c) for dev in self.devices.values() for c in dev.tasks()]
        # READY once the ports are open (or 5 s have shown which are not) and the loop ticks
        down = await wait_open(self.devices, self.clock, 5.0)
        self.notifier.ready("navigating" + (f"; not open: {', '.join(down)}" if down else ""))
        log.info("navd running; devices not open: %s", down or "none")
        try:
            await stop.wait()
        finally:
            self.notifier.stopping()
            for t in tasks:
                t.cancel()
            try:
                await asyncio.wait_for(self._stop(tasks), STOP_TIMEOUT_S)
            except TimeoutError:
                log.error("stopping took over %g s; closing the log regardless", STOP_TIMEOUT_S)
            self.rlog.close()

    async def _stop(self, tasks: list[asyncio.Task[None]]) -> None:
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await t
        for dev in self.devices.values():
            await dev.transport.stop()
        if self.pub is not None:
            self.pub.close()

