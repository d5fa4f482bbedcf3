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
from typing import Any

from navd.config import log_dir
from navd.daemon.checkpoint import (
    Checkpoints,
    checkpoint_dir,
    config_digest,
    number_or_none,
    resume_record,
)
from navd.daemon.devices import Device, make_devices
from navd.daemon.devices.base import HealthSections
from navd.daemon.devices.modem import idle_sections
from navd.daemon.health import RECENT_S, TickTimes, Vitals
from navd.daemon.publish import BeaconCommand, Command, ResetCommand
from navd.daemon.sdnotify import Notifier
from navd.drivers.codec import DecodeStats
from navd.drivers.transport import SerialTransport
from navd.filter import Navigator
from navd.formats.log import RecordLog
from navd.records import MAX_BEACONS, Reset, SetBeacon
from navd.schema import Estimate, Health, Output, RangeDecision
from navd.settings import Config

log = logging.getLogger("navd")
LOG_FLUSH_S = 0.25  # kill -9 loses at most this much of the log
RESET_SPACING_S = 10.0  # any reset at most this often
FORCED_RESET_SPACING_S = 60.0  # a forced one (it stops navigation until the next fix)
ZENOH_OPEN_WARN_S = 5.0  # a session not open by then is said in health (it goes on trying)
STOP_TIMEOUT_S = 10.0  # inside the unit's TimeoutStopSec (15 s): the log is closed in time


class _Logged:
    """A decoder wrapper that logs the raw bytes before decoding them."""

    def __init__(self, name: str, inner: Any, rlog: RecordLog) -> None:
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
        publisher_factory: Callable[..., Any] | None = None,
    ) -> None:
        self.cfg = cfg
        self.clock = clock
        self.notifier = notifier or Notifier()
        self.nav = Navigator(cfg)
        lc = cfg.log
        self.rlog = RecordLog(
            log_dir(cfg, os.environ),
            lc.rotate_mb,
            lc.raw_bytes,
            lc.raw_budget_bytes_per_s,
            lc.keep_mb,
        )
        self.publisher_factory = publisher_factory
        self.pub: Any = None
        where = checkpoint_dir(cfg, os.environ)
        self.checkpoints = (
            Checkpoints(where, cfg.vehicle.name, config_digest(cfg)) if where is not None else None
        )
        self.resumed: dict[str, Any] | None = None  # what this run resumed from, if anything
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
        self._t_internal_error: float | None = None
        self.zenoh_error = ""  # why the zenoh session is not open, while it is not
        self._t_reset = -math.inf  # the last accepted reset, and the last forced one
        self._t_forced = -math.inf

    # -- records in ------------------------------------------------------------------
    def feed(self, rec: Any) -> None:
        """A measurement, stamped with its arrival, to the log and the filter."""
        self.rlog.record(rec)
        try:
            outs = self.nav.feed(rec)
        except Exception as exc:
            self._navigator_failed(exc)
            return
        self._outputs(outs)

    def _navigator_failed(self, exc: Exception) -> None:
        # The core is meant to be total (tests/test_navigator_total.py); if it still
        # raises, its state may be half updated, so it starts again from the next fix.
        kind = f"navigator: {exc.__class__.__name__}"
        n = self.internal_errors.get(kind, 0)
        self.internal_errors[kind] = n + 1
        self._t_internal_error = self.clock()
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
        if self.nav.mode(t) == "submerged" and not force:
            # submerged, the filter cannot start again until the vehicle surfaces
            return "submerged: a reset stops navigation until the next GPS fix; send force"
        # each reset stops the estimates until the next fix: their rate is bounded so
        # that no run of them, however well-formed, can keep navd from navigating
        since = t - self._t_reset
        if since < RESET_SPACING_S:
            return f"a reset {since:.1f} s ago: at most one every {RESET_SPACING_S:g} s"
        if force and t - self._t_forced < FORCED_RESET_SPACING_S:
            return f"a forced reset at most once every {FORCED_RESET_SPACING_S:g} s"
        self._t_reset = t
        if force:
            self._t_forced = t
        self.feed(Reset(t))
        if self.pub is not None:
            self.pub.forget_latest()
        return None

    # -- tasks -------------------------------------------------------------------------
    def _start_devices(self) -> None:
        for dev in self.devices.values():
            dev.transport = SerialTransport(
                dev.cfg.url,
                dev.cfg.baudrate,
                _Logged(dev.name, dev.decoder, self.rlog),
                dev.handle,
                on_open=dev.on_open,
                clock=self.clock,
            )
            dev.transport.start()

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
                and self._navigating(now)
            ):
                # from the loop itself, and only while estimates come out: systemd
                # restarts a daemon whose loop hangs or whose navigation is dead
                self.notifier.watchdog()
                self._last_watchdog = now
            k += 1

    def _navigating(self, now: float) -> bool:
        """Estimates are coming out, or the filter is waiting for its first position."""
        if not self.nav.filter.initialised:
            return True
        last = self.vitals.estimates[-1] if self.vitals.estimates else self.vitals.t_started
        return now - last <= 2.0

    async def _zenoh(self) -> None:
        """Open the zenoh session, and keep trying while it cannot be (port in use, bad
        endpoint): navigation and the log do not wait for it."""
        if self.publisher_factory is None:
            return
        loop = asyncio.get_running_loop()
        delay = 1.0
        while self.pub is None:
            try:
                # zenoh.open blocks (name resolution, a slow file, a router that does not
                # answer): in a thread, so that navigation never waits for it
                opening = asyncio.ensure_future(
                    asyncio.to_thread(self.publisher_factory, loop, self.on_command)
                )
                while not opening.done():
                    await asyncio.wait({opening}, timeout=ZENOH_OPEN_WARN_S)
                    if not opening.done():
                        self.zenoh_error = f"still opening after {ZENOH_OPEN_WARN_S:g} s"
                self.pub = opening.result()
                self.zenoh_error = ""
                log.info("zenoh session open")
            except Exception as exc:  # zenoh raises its own ZError, and OSError
                if delay == 1.0:
                    log.error("zenoh: cannot open the session (%s); retrying", exc)
                self.zenoh_error = f"{exc.__class__.__name__}: {exc}"[:200]
                await asyncio.sleep(delay)
                delay = min(30.0, delay * 2)

    async def _log_flusher(self) -> None:
        last_sync = self.clock()
        while True:
            await asyncio.sleep(LOG_FLUSH_S)
            if self.clock() - last_sync >= self.cfg.log.fsync_s:
                self.rlog.sync()
                last_sync = self.clock()
            else:
                self.rlog.flush()

    async def _health(self) -> None:
        while True:
            await asyncio.sleep(1.0)
            now = self.clock()
            for dev in self.devices.values():
                dev.every_second(now)
            h = self.health()
            self.rlog.output(h)
            heading = self.latest.heading_deg if self.latest else None
            adv = self.nav.advisory(now, heading)
            self.rlog.output(adv)
            if self.pub is not None:
                self.pub.put(h)
                self.pub.put(adv)

    def health(self) -> Health:
        now = self.clock()
        devices = {name: dev.health(now) for name, dev in self.devices.items()}
        # each device's own sections; a device navd has not says nothing, or idles
        own: HealthSections = {"temperature_c": None, "gps_utc": None, "esc": {}}
        own.update(idle_sections())
        for dev in self.devices.values():
            own.update(dev.sections())
        est = self.latest
        mode = est.mode if est else "waiting_for_gps"
        self.vitals.mode(now, mode)
        d = self.cfg.devices
        source = {"heading": d.ahrs, "rpm": d.motor, "depth": d.pressure}
        ages = {k: v for k, v in self.nav.input_ages(now).items() if source[k].enabled}
        degraded = self.vitals.problems(now, self.nav.filter.initialised, ages)
        integrity = est.integrity if est else "lost"
        if integrity != "ok" and self.nav.filter.initialised:
            why = (est.integrity_reason if est else None) or ""
            degraded.append(f"integrity {integrity}: {why}")
        for n, dev in self.devices.items():
            degraded += dev.problems(now, devices[n])
        if self._t_internal_error is not None and now - self._t_internal_error <= RECENT_S:
            degraded.append(f"internal errors {self.internal_errors}")
        if self.rlog.degraded and self.rlog.errors:
            degraded.append("log")
        if self.publisher_factory is not None and self.pub is None:
            degraded.append(f"zenoh: not open ({self.zenoh_error or 'opening'}), retrying")
        return Health(
            t=now,
            mode=mode,
            integrity=integrity if self.nav.filter.initialised else "lost",
            ok=not degraded,
            degraded=degraded,
            estimates_per_s=self.vitals.estimates_per_s(now),
            input_age_s={k: None if v is None else round(v, 3) for k, v in ages.items()},
            last_range_accepted_age_s=None
            if self.vitals.t_range_accepted is None
            else round(now - self.vitals.t_range_accepted, 3),
            devices=devices,
            pings={**own["pings"], "fused": self.fused, "last": list(self.vitals.pings)},
            modem=own["modem"],
            filter=dict(self.nav.counters),
            ticks=self.times.ticks,
            tick_overruns=self.times.overruns,
            tick_lateness_ms=self.times.lateness_ms(),
            publish_latency_ms=self.times.publish_ms(),
            log=self.rlog.section(),
            checkpoint=None if self.checkpoints is None else self.checkpoints.section(self.resumed),
            zenoh={"open": False, "error": self.zenoh_error}
            if self.pub is None
            else self.pub.section(),
            temperature_c=own["temperature_c"],
            gps_utc=own["gps_utc"],
            esc=own["esc"],
        )

    def _resume(self) -> None:
        """A checkpoint of this vehicle and config, young enough: navigate on from it."""
        if self.checkpoints is None:
            return
        path = self.checkpoints.path
        snap, said = self.checkpoints.load(self.cfg.checkpoint.max_age_s)
        if snap is None:
            if said:
                log.warning("%s", said)
            return
        t = self.clock()
        rec = resume_record(snap, t)
        if isinstance(rec, str):
            log.warning("checkpoint ignored: %s: %s", path, rec)
            return
        self.feed(rec)  # logged as cmd_resume: a replay of the log resumes the same
        if self.nav.counters.get("resumed"):
            self.resumed = {
                "t": t,
                "age_s": round(rec.age_s, 1),
                "lat": number_or_none(snap.get("lat")),
                "lon": number_or_none(snap.get("lon")),
            }
            log.info("resumed navigation from a checkpoint %.0f s old", rec.age_s)
        else:
            log.warning("checkpoint ignored: the filter refused it (%s)", dict(self.nav.counters))

    async def _checkpointer(self) -> None:
        if self.checkpoints is None:
            return
        while True:
            await asyncio.sleep(self.cfg.checkpoint.every_s)
            snap = self.nav.snapshot()  # taken here, between two ticks: one consistent state
            if snap is not None:
                # the write ends in an fsync, which an SD card can take 100 ms over
                await asyncio.to_thread(self.checkpoints.write, snap)

    async def run(self, stop: asyncio.Event) -> None:
        loop = asyncio.get_running_loop()
        self._resume()
        self._start_devices()
        tasks = [
            loop.create_task(self._checkpointer()),
            loop.create_task(self._zenoh()),
            loop.create_task(self._ticker()),
            loop.create_task(self._health()),
            loop.create_task(self._log_flusher()),
        ]
        tasks += [loop.create_task(c) for dev in self.devices.values() for c in dev.tasks()]
        # READY once the ports are open (or 5 s have shown which are not) and the loop ticks
        t_end = self.clock() + 5.0
        while self.clock() < t_end and not all(d.connected for d in self.devices.values()):
            await asyncio.sleep(0.05)
        down = [n for n, d in self.devices.items() if not d.connected]
        self.notifier.ready("navigating" + (f"; not open: {', '.join(down)}" if down else ""))
        for name in down:  # one line each, with why: the journal is where a crew looks first
            tr = self.devices[name].transport
            why = (tr.health.last_error if tr else "") or "no answer yet"
            log.warning("%s: not open (%s); retrying", name, why)
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
        for s in self.devices.values():
            if s.transport:
                await s.transport.stop()
        if self.pub is not None:
            self.pub.close()

