"""``navd run``: the daemon the vehicle runs.

One asyncio task per serial device (navd/drivers/transport.py), a 10 Hz filter tick on
absolute monotonic deadlines, a ping scheduler (``ATRX`` every ``ping_interval_s``,
never two outstanding, a reply timeout), a 1 Hz health task, zenoh publishing and
the crash-safe log.  Every measurement is stamped with the monotonic time its bytes
arrived and fed to the same :class:`~navd.filter.Navigator` that ``navd replay``
runs, so the log replays to the same estimates.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import logging
import math
import os
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from navd.config import Config, log_dir
from navd.daemon.health import RECENT_S, Vitals
from navd.daemon.sdnotify import Notifier
from navd.drivers import ahrs, castle, gps, keller, modem
from navd.drivers.codec import DecodeStats, DeviceError
from navd.drivers.transport import SerialTransport
from navd.filter import Navigator
from navd.formats.log import RecordLog
from navd.records import Gps, Pressure, Range, Reset, Rpm, SetBeacon
from navd.schema import DeviceHealth, Health, to_dict

log = logging.getLogger("navd")
LOG_FLUSH_S = 0.25  # kill -9 loses at most this much of the log
# a burst of corrupt data: this many bad frames within the window is said in health
CORRUPT_FRAMES = 3
CORRUPT_BYTES = 64
CORRUPT_WINDOW_S = 5.0
SILENT_S = 3.0  # a streaming or polled device this long without a byte is said silent
PROBE_WAIT_S = 3.0  # a device asked who it is answers within this
AHRS_RESET_S = 10.0  # an open AHRS silent this long is soft-reset (at most this often)
AHRS_RESET_WAIT_S = 1.0  # from the soft reset to setting it up again
_NMEA_MAX_HZ = 10.0  # GGA and RMC at 5 Hz, the fastest a navigation receiver is set to
STOP_TIMEOUT_S = 10.0  # inside the unit's TimeoutStopSec (15 s): the log is closed in time
MAX_BEACONS = 16  # configured and commanded: bounds what a command can make navd keep


class _Logged:
    """A decoder wrapper that logs the raw bytes before decoding them."""

    def __init__(self, name: str, inner: Any, rlog: RecordLog) -> None:
        self.name, self.inner, self.rlog = name, inner, rlog
        self.stats: DecodeStats = inner.stats  # the same counters, not a copy

    def feed(self, data: bytes, t: float) -> list[object]:
        self.rlog.raw_bytes(t, self.name, data)
        return self.inner.feed(data, t)


@dataclass(slots=True)
class DeviceState:
    name: str
    transport: SerialTransport | None = None
    decoder: Any = None
    records: int = 0
    recent: deque[float] = field(default_factory=lambda: deque(maxlen=2000))
    device_errors: int = 0  # the device answered with an error in place of a reading
    t_device_error: float | None = None
    last_device_error: str = ""
    t_probe: float | None = None  # since when the device has been asked who it is
    t_probe_sent: float = -math.inf  # when it was last asked
    # what the device said of itself (firmware, serial number, calibration): in health
    info: dict[str, Any] = field(default_factory=dict)
    eeprom: dict[int, int] = field(default_factory=dict)
    t_reset: float = -math.inf  # the last soft reset navd sent (the AHRS)
    resets: int = 0
    # (t, bad frames, skipped bytes) at each health tick: what the last seconds brought
    bad_history: deque[tuple[float, int, int]] = field(default_factory=deque)


def _percentile(xs: list[float], q: float) -> float | None:
    if not xs:
        return None
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))]


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
        self.devices: dict[str, DeviceState] = {}
        self.dt = 1.0 / cfg.navigation.rate_hz
        self.tick_lateness: deque[float] = deque(maxlen=6000)
        self.publish_latency: deque[float] = deque(maxlen=6000)
        self.overruns = 0
        self.ticks = 0
        self.ping_t: float | None = None
        self.modem_session = modem.ModemSession()
        self.pings = {
            "sent": 0,
            "ranges": 0,
            "fused": 0,  # range decisions the filter made: every range should get one
            "no_reply": 0,
            "refused": 0,  # ERROR, or the shell's "Command '...' not found"
            "timeouts": 0,
            "errors": 0,  # ranges nobody asked for
            "skipped_busy": 0,
            "skipped_not_in_command_mode": 0,
            "skipped_port_down": 0,
        }
        self.latest: dict[str, Any] | None = None
        self.gps_utc: dt.datetime | None = None
        self.temperature_c: float | None = None
        # the motor controller's battery voltage, current and temperature
        self.esc: dict[str, float] = {}
        self._last_watchdog = -math.inf
        m = cfg.devices.modem
        self.vitals = Vitals(
            cfg.navigation.rate_hz,
            m.ping_interval_s,
            max(cfg.navigation.stale_input_s, 2.0),
            t_started=clock(),
        )
        # exceptions of the navigator, by kind: caught so one bad record cannot stop
        # the daemon, logged once, shown in health
        self.internal_errors: dict[str, int] = {}
        self._t_internal_error: float | None = None
        self.zenoh_error = ""  # why the zenoh session is not open, while it is not

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

    def _outputs(self, outs: list[dict[str, Any]]) -> None:
        for o in outs:
            self.rlog.output(o)
            if o["type"] == "estimate":
                self._publish_estimate(o)
                continue
            self.pings["fused"] += 1
            if o.get("accepted"):
                self.vitals.range_accepted(self.clock())
            if self.pub is not None:
                self.pub.put("range", o)

    def _publish_estimate(self, est: dict[str, Any]) -> None:
        body = dict(est)
        body["t_utc"] = dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")
        self.latest = body
        self.vitals.estimate(self.clock())
        if self.pub is not None:
            self.pub.put("estimate", body)
        self.publish_latency.append(self.clock() - est["t"])

    def _on_record(self, name: str) -> Callable[[object], None]:
        state = self.devices[name]

        def handle(rec: object) -> None:
            if isinstance(rec, DeviceError):
                self._on_device_error(state, rec)
                return
            state.records += 1
            state.recent.append(self.clock())
            if isinstance(rec, ahrs.Euler):
                self.feed(rec.attitude)
            elif isinstance(rec, Gps | Pressure | Rpm):
                self.feed(rec)
            elif isinstance(rec, gps.GpsTime):
                self.gps_utc = rec.utc or self.gps_utc
            elif isinstance(rec, keller.Temperature):
                self.temperature_c = rec.c
            elif isinstance(rec, ahrs.Firmware):
                state.info["firmware"] = rec.version
            elif isinstance(rec, ahrs.EepromWord):
                self._on_eeprom(state, rec)
            elif isinstance(rec, keller.SerialNumber):
                if state.info.get("serial_number") != rec.number:
                    log.info("%s: serial number %d", name, rec.number)
                state.info["serial_number"] = rec.number
            elif isinstance(rec, castle.EscStatus):
                self.esc[rec.name] = round(rec.value, 2)
            elif isinstance(rec, modem.ModemRange):
                self._on_range(rec)
            elif isinstance(rec, modem.ModemReply):
                self.modem_session.seen(rec)
                self._on_modem_reply(rec)
            elif isinstance(rec, modem.ModemMode):
                self.modem_session.seen(rec)

        return handle

    def _on_eeprom(self, state: DeviceState, rec: ahrs.EepromWord) -> None:
        state.eeprom[rec.address] = rec.value
        words = [state.eeprom.get(ahrs.HARD_IRON_ADDR + 2 * i) for i in range(6)]
        if all(w is not None for w in words):
            offsets = ahrs.hard_iron([w for w in words if w is not None])
            state.info["hard_iron"] = [round(x, 6) if math.isfinite(x) else None for x in offsets]

    def _on_device_error(self, state: DeviceState, rec: DeviceError) -> None:
        """An error answer is not a reading: counted apart, and shown in health."""
        state.device_errors += 1
        state.t_device_error = self.clock()
        state.last_device_error = rec.what
        if rec.send and state.transport is not None:
            state.transport.write(rec.send)  # e.g. a Keller that forgot F48 after a power blip

    def _on_range(self, r: modem.ModemRange) -> None:
        if self.ping_t is None:
            self.pings["errors"] += 1  # a range we did not ask for
            return
        m = self.cfg.devices.modem
        self.pings["ranges"] += 1
        self.vitals.ping("range")
        t_ping, self.ping_t = self.ping_t, None
        self.feed(
            Range(r.t, t_ping, r.range_m, m.beacon, r.lat, r.lon, r.depth, r.twtt_s, r.speed_mps)
        )

    def _on_modem_reply(self, r: modem.ModemReply) -> None:
        # "OK" follows a range, which already closed the ping; silence or a refusal close it
        if r.status == "refused":
            self.pings["refused"] += 1  # counted even when no ping was waiting
        if r.status in ("no_reply", "refused") and self.ping_t is not None:
            if r.status == "no_reply":
                self.pings["no_reply"] += 1
            self.vitals.ping(r.status)
            self.ping_t = None

    # -- commands from the autopilot (zenoh thread -> loop) -----------------------------
    def on_command(self, name: str, body: dict[str, Any]) -> str | None:
        """A validated command, or why it is refused (None: done).

        It is fed like a measurement, so the log keeps it and replay redoes it.
        """
        t = self.clock()
        if name == "reset":
            if self.nav.mode(t) == "submerged" and not body.get("force"):
                # submerged, the filter cannot start again until the vehicle surfaces
                return "submerged: a reset stops navigation until the next GPS fix; send force"
            self.feed(Reset(t))
        elif name == "beacon":
            known = self.nav.beacons.beacons
            if body["name"] not in known and len(known) >= MAX_BEACONS:
                return f"at most {MAX_BEACONS} beacons"
            self.feed(SetBeacon(t, body["name"], body["lat"], body["lon"], body.get("depth", 0.0)))
        return None

    # -- tasks -------------------------------------------------------------------------
    def _start_devices(self) -> None:
        d = self.cfg.devices
        specs: list[tuple[str, Any, Any, Callable[[SerialTransport], None] | None]] = []
        if d.ahrs.enabled:
            ad = ahrs.AhrsDecoder()

            def ahrs_open(tr: SerialTransport, rate: float = d.ahrs.rate_hz) -> None:
                tr.write(ahrs.encode_stop())
                # which unit is this: a single-byte 3DM-GX3-25 answers with its firmware;
                # was its compass ever calibrated: its hard-iron offsets
                st = self.devices["ahrs"]
                st.t_probe = st.t_probe_sent = self.clock()
                st.info.clear()
                st.eeprom.clear()
                tr.write(ahrs.encode_firmware_probe())
                tr.write(ad.request_hard_iron())
                tr.write(ahrs.encode_sampling(rate))
                tr.write(ahrs.encode_continuous())

            specs.append(("ahrs", d.ahrs, ad, ahrs_open))
        if d.gps.enabled:
            specs.append(("gps", d.gps, gps.NmeaDecoder(), None))
        if d.pressure.enabled:
            kd = keller.KellerDecoder(d.pressure.address, d.pressure.local_echo)

            def keller_open(tr: SerialTransport, kd: keller.KellerDecoder = kd) -> None:
                tr.write(kd.request_init())
                tr.write(kd.request_serial())  # which sensor: in health and the journal

            specs.append(("pressure", d.pressure, kd, keller_open))
        if d.motor.enabled:
            cd = castle.CastleDecoder(d.motor.pole_pairs, d.motor.device_id)

            def motor_open(tr: SerialTransport, cd: castle.CastleDecoder = cd) -> None:
                tr.write(cd.request_clear())  # a half request left in the ESC is dropped

            specs.append(("motor", d.motor, cd, motor_open))
        if d.modem.enabled:

            def modem_open(tr: SerialTransport) -> None:
                self.modem_session.opened(self.clock())

            specs.append(("modem", d.modem, modem.ModemDecoder(), modem_open))
        for name, dev, dec, on_open in specs:
            self.devices[name] = DeviceState(name, decoder=dec)
            tr = SerialTransport(
                dev.port,
                dev.baudrate,
                _Logged(name, dec, self.rlog),
                self._on_record(name),
                on_open=on_open,
                clock=self.clock,
            )
            self.devices[name].transport = tr
            tr.start()

    async def _poller(self, name: str, hz: float, request: Callable[[], bytes]) -> None:
        period = 1.0 / hz
        nxt = self.clock()
        while True:
            nxt += period
            await asyncio.sleep(max(0.0, nxt - self.clock()))
            tr = self.devices[name].transport
            if tr is not None and tr.health.connected:
                tr.write(request())

    async def _pinger(self) -> None:
        m = self.cfg.devices.modem
        while True:
            await asyncio.sleep(m.ping_interval_s)
            now = self.clock()
            if self.ping_t is not None:
                if now - self.ping_t < m.reply_timeout_s:
                    self.pings["skipped_busy"] += 1
                    continue
                self._ping_lost()
            tr = self.devices["modem"].transport
            if tr is None or not tr.health.connected:
                self.pings["skipped_port_down"] += 1
                continue
            if not self.modem_session.ready:
                self.pings["skipped_not_in_command_mode"] += 1
                continue
            self.ping_t = self.clock()
            if tr.write(modem.encode_range(m.remote_address)):
                self.pings["sent"] += 1
                self.modem_session.wrote(self.ping_t)
            else:
                self.ping_t = None

    def _ping_lost(self) -> None:
        """The modem never closed the last ping, not even with "Response Not Received.":
        it is not listening to commands (online, asleep), so it is brought back."""
        self.pings["timeouts"] += 1
        self.vitals.ping("timeout")
        self.ping_t = None
        self.modem_session.lost(self.clock())

    async def _modem_keeper(self) -> None:
        """Bring the modem into command mode and keep it there (navd.drivers.modem.ModemSession)."""
        while True:
            await asyncio.sleep(0.1)
            tr = self.devices["modem"].transport
            if tr is None or not tr.health.connected:
                continue
            data = self.modem_session.poll(self.clock())
            if data:
                tr.write(data)

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
            self.tick_lateness.append(late)
            if late > dt_:
                self.overruns += 1
                k = math.floor(now / dt_)  # catch up: the navigator emits every missed tick
            if "modem" in self.devices:
                # a range whose location line never came is complete after a short wait
                for rec in self.devices["modem"].decoder.expire(now):
                    self._on_record("modem")(rec)
            try:
                self._outputs(self.nav.advance(k * dt_))
            except Exception as exc:
                self._navigator_failed(exc)
            self.ticks += 1
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
                self.pub = self.publisher_factory(loop, self.on_command)
                self.zenoh_error = ""
                log.info("zenoh session open")
            except Exception as exc:  # zenoh raises its own ZError, and OSError
                if not self.zenoh_error:
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
            m = self.cfg.devices.modem
            if self.ping_t is not None and self.clock() - self.ping_t > m.reply_timeout_s:
                self._ping_lost()
            self._recover_ahrs()
            h = self.health()
            self.rlog.output(h)
            if self.pub is not None:
                self.pub.put("health", h)

    def _recover_ahrs(self) -> None:
        """An AHRS whose port is open but which has said nothing for ``AHRS_RESET_S`` is
        soft-reset and set up again (as after an open): a unit that lost its settings
        in a brown-out streams nothing until told again."""
        st = self.devices.get("ahrs")
        tr = st.transport if st else None
        if st is None or tr is None or not tr.health.connected or tr.on_open is None:
            return
        now = self.clock()
        if "firmware" not in st.info and now - st.t_probe_sent > PROBE_WAIT_S:
            # unanswered (a stalled or resetting unit): ask again until it says who it is
            st.t_probe_sent = now
            tr.write(ahrs.encode_firmware_probe())
            if "hard_iron" not in st.info:
                tr.write(st.decoder.request_hard_iron())
        last = max(tr.health.last_rx or -math.inf, st.t_probe or -math.inf, st.t_reset)
        if now - last < AHRS_RESET_S:
            return
        st.t_reset = now
        st.resets += 1
        tr.write(ahrs.encode_soft_reset())
        asyncio.get_running_loop().call_later(AHRS_RESET_WAIT_S, tr.on_open, tr)

    def _recent_bad(self, st: DeviceState, now: float) -> tuple[int, int]:
        """Bad frames (checksum or content) and skipped bytes in the last ``CORRUPT_WINDOW_S``."""
        stats = st.decoder.stats
        st.bad_history.append((now, stats.bad_checksum + stats.bad_frame, stats.skipped_bytes))
        while len(st.bad_history) > 1 and now - st.bad_history[1][0] >= CORRUPT_WINDOW_S:
            st.bad_history.popleft()
        _, bad0, skipped0 = st.bad_history[0]
        _, bad1, skipped1 = st.bad_history[-1]
        return bad1 - bad0, skipped1 - skipped0

    def _expected_rate(self, name: str) -> float | None:
        """Records a second the device should give: what navd asks of it, or None."""
        d = self.cfg.devices
        return {
            "ahrs": d.ahrs.rate_hz,
            "pressure": d.pressure.poll_hz,
            "motor": d.motor.poll_hz,
            "gps": _NMEA_MAX_HZ,
        }.get(name)

    def health(self) -> dict[str, Any]:
        now = self.clock()
        devices = {}
        for name, st in self.devices.items():
            hl = st.transport.health if st.transport else None
            stats = st.decoder.stats
            rate = sum(1 for x in st.recent if now - x <= 5.0) / 5.0
            devices[name] = DeviceHealth(
                connected=bool(hl and hl.connected),
                last_rx_age_s=None if not hl or hl.last_rx is None else round(now - hl.last_rx, 3),
                rate_hz=rate,
                records=st.records,
                bad_checksum=stats.bad_checksum,
                bad_frame=stats.bad_frame,
                skipped_bytes=stats.skipped_bytes,
                reconnects=hl.reconnects if hl else 0,
                opens=hl.opens if hl else 0,
                read_errors=hl.read_errors if hl else 0,
                write_errors=hl.write_errors if hl else 0,
                last_error=hl.last_error if hl else "",
                device_errors=st.device_errors,
                resets=st.resets,
                last_device_error=st.last_device_error,
                info=dict(st.info),
                internal_errors=dict(hl.internal_errors) if hl else {},
            )
        lat = list(self.tick_lateness)
        est = self.latest or {}
        mode = est.get("mode", "waiting_for_gps")
        self.vitals.mode(now, mode)
        d = self.cfg.devices
        source = {"heading": d.ahrs, "rpm": d.motor, "depth": d.pressure}
        ages = {k: v for k, v in self.nav.input_ages(now).items() if source[k].enabled}
        degraded = self.vitals.problems(now, self.nav.filter.initialised, ages)
        integrity = est.get("integrity", "lost")
        if integrity != "ok" and self.nav.filter.initialised:
            degraded.append(f"integrity {integrity}: {est.get('integrity_reason', '')}")
        degraded += [f"{n} disconnected" for n, dv in devices.items() if not dv.connected]
        for n, st in self.devices.items():
            bad, skipped = self._recent_bad(st, now)
            if bad >= CORRUPT_FRAMES or skipped >= CORRUPT_BYTES:
                degraded.append(
                    f"{n}: {bad} corrupt frames, {skipped} bytes skipped in {CORRUPT_WINDOW_S:g} s"
                )
            expected = self._expected_rate(n)
            age = devices[n].last_rx_age_s
            if expected is not None and age is not None and age > SILENT_S:
                degraded.append(f"{n}: silent for {age:.0f} s")
            if expected is not None and devices[n].rate_hz > 2.0 * expected + 1.0:
                degraded.append(f"{n}: {devices[n].rate_hz:.0f} records/s, {expected:g} expected")
            if (
                st.t_probe is not None
                and "firmware" not in st.info
                and now - st.t_probe > PROBE_WAIT_S
                and devices[n].connected
            ):
                degraded.append(
                    f"{n}: no answer to the firmware probe: not a single-byte protocol unit?"
                )
            if st.t_device_error is not None and now - st.t_device_error <= RECENT_S:
                degraded.append(
                    f"{n}: device error answers ({st.device_errors}, last: {st.last_device_error})"
                )
            hl = st.transport.health if st.transport else None
            if hl and hl.last_internal_error and now - hl.last_internal_error <= RECENT_S:
                degraded.append(f"{n}: internal errors {hl.internal_errors}")
        if self._t_internal_error is not None and now - self._t_internal_error <= RECENT_S:
            degraded.append(f"internal errors {self.internal_errors}")
        ms = self.modem_session
        if "modem" in self.devices and ms.t_unready is not None and now - ms.t_unready > 10.0:
            degraded.append(
                f"modem: not in command mode for {now - ms.t_unready:.0f} s "
                f"(last said: {ms.mode}, {ms.escapes} escapes)"
            )
        if self.rlog.degraded and self.rlog.errors:
            degraded.append("log")
        if self.publisher_factory is not None and self.pub is None:
            degraded.append(f"zenoh: not open ({self.zenoh_error or 'opening'}), retrying")
        return to_dict(
            Health(
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
                pings={**self.pings, "last": list(self.vitals.pings)},
                modem={
                    "mode": self.modem_session.mode,
                    "ready": self.modem_session.ready,
                    "escapes": self.modem_session.escapes,
                },
                filter=dict(self.nav.counters),
                ticks=self.ticks,
                tick_overruns=self.overruns,
                tick_lateness_ms={
                    "p50": _ms(_percentile(lat, 0.5)),
                    "p99": _ms(_percentile(lat, 0.99)),
                    "max": _ms(max(lat) if lat else None),
                },
                # from the tick's deadline to the estimate handed to zenoh
                publish_latency_ms={
                    "p50": _ms(_percentile(list(self.publish_latency), 0.5)),
                    "p99": _ms(_percentile(list(self.publish_latency), 0.99)),
                },
                log={
                    "file": str(self.rlog.path) if self.rlog.path else None,
                    "ok": not (self.rlog.degraded and self.rlog.errors),
                    "lines": self.rlog.lines,
                    "errors": self.rlog.errors,
                    "dropped": self.rlog.dropped,
                    "raw_bytes_over_budget": dict(self.rlog.raw_dropped),
                    "files_removed": self.rlog.removed_files,
                    "last_error": self.rlog.last_error,
                },
                zenoh={"open": False, "error": self.zenoh_error}
                if self.pub is None
                else {
                    "open": True,
                    "errors": self.pub.errors,
                    "commands": dict(self.pub.commands),
                },
                temperature_c=self.temperature_c,
                # the receiver's last UTC (RMC): against t_utc of the estimates, the clock's error
                gps_utc=self.gps_utc.isoformat() if self.gps_utc else None,
                esc=dict(self.esc),
            )
        )

    async def run(self, stop: asyncio.Event) -> None:
        loop = asyncio.get_running_loop()
        self._start_devices()
        d = self.cfg.devices
        tasks = [
            loop.create_task(self._zenoh()),
            loop.create_task(self._ticker()),
            loop.create_task(self._health()),
            loop.create_task(self._log_flusher()),
        ]
        if d.pressure.enabled:
            kd = self.devices["pressure"].decoder
            tasks.append(
                loop.create_task(
                    self._poller(
                        "pressure", d.pressure.poll_hz, lambda: kd.request(keller.CH_PRESSURE)
                    )
                )
            )
        if d.motor.enabled:
            cd = self.devices["motor"].decoder
            tasks.append(loop.create_task(self._poller("motor", d.motor.poll_hz, cd.request_poll)))
        if d.modem.enabled:
            tasks.append(loop.create_task(self._modem_keeper()))
            tasks.append(loop.create_task(self._pinger()))
        # READY once the ports are open (or 5 s have shown which are not) and the loop ticks
        t_end = self.clock() + 5.0
        while self.clock() < t_end and not all(
            s.transport and s.transport.health.connected for s in self.devices.values()
        ):
            await asyncio.sleep(0.05)
        down = [
            n for n, s in self.devices.items() if not (s.transport and s.transport.health.connected)
        ]
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
        for s in self.devices.values():
            if s.transport:
                await s.transport.stop()
        if self.pub is not None:
            self.pub.close()


def _ms(x: float | None) -> float | None:
    return None if x is None else round(x * 1000.0, 3)
