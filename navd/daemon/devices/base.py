"""What every device has: a port, a decoder, counters, and the health they add up to."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Coroutine
from typing import Protocol, TypedDict

from navd.daemon import pace
from navd.daemon.health import RECENT_S, Vitals
from navd.drivers.codec import Decoder, DeviceError
from navd.drivers.transport import SerialTransport
from navd.records import Record
from navd.schema import DeviceHealth
from navd.settings import SerialPortConfig

# a burst of corrupt data: this many bad frames within the window is said in health
CORRUPT_FRAMES = 3
CORRUPT_BYTES = 64
CORRUPT_WINDOW_S = 5.0
SILENT_S = 3.0  # a streaming or polled device this long without a byte is said silent

#: what a device runs while the daemon does (its polls, its pings)
Job = Coroutine[object, object, None]


class Host(Protocol):
    """What a device may ask of the daemon around it."""

    vitals: Vitals

    def clock(self) -> float: ...

    def feed(self, rec: Record) -> None: ...

    def logged(self, name: str, decoder: Decoder) -> Decoder:
        """``decoder`` with the raw bytes it is fed kept in the log first."""
        ...


class HealthSections(TypedDict, total=False):
    """The sections of health's top level that belong to one device (docs/schema.md)."""

    pings: dict[str, object]  # the modem's
    modem: dict[str, object]
    temperature_c: float | None  # the pressure sensor's
    gps_utc: str | None  # the GPS receiver's last UTC
    esc: dict[str, float]  # the motor controller's battery, current, temperature


class Device:
    """A serial device. Subclasses say what to send on open, what to poll, and what
    their records mean (:meth:`on_record`)."""

    name = ""
    #: records a second navd asks of the device (None: it speaks when spoken to)
    expected_rate_hz: float | None = None

    def __init__(self, cfg: SerialPortConfig, host: Host, decoder: Decoder) -> None:
        self.cfg = cfg
        self.host = host
        self.decoder = decoder
        # made here and opened by start(): a device always has its port
        self.transport = SerialTransport(
            cfg.url,
            cfg.baudrate,
            host.logged(self.name, decoder),
            self.handle,
            on_open=self.on_open,
            clock=host.clock,
        )
        self.records = 0
        self.recent: deque[float] = deque(maxlen=2000)
        self.device_errors = 0  # the device answered with an error in place of a reading
        self.t_device_error: float | None = None
        self.last_device_error = ""
        # what the device said of itself (firmware, serial number, calibration): in health
        self.info: dict[str, object] = {}
        self.resets = 0
        # (t, bad frames, skipped bytes) at each health tick: what the last seconds brought
        self.bad_history: deque[tuple[float, int, int]] = deque()

    # -- what subclasses say ----------------------------------------------------------
    def on_open(self, tr: SerialTransport) -> None:
        """Sent each time the port opens (a device may have lost power since)."""

    def on_record(self, rec: object) -> None:
        raise NotImplementedError

    def tasks(self) -> list[Job]:
        """Coroutines that run while the daemon does (polls, pings)."""
        return []

    def on_tick(self, now: float) -> None:
        """Called at the filter rate, before the filter steps."""

    def every_second(self, now: float) -> None:
        """Called once a second, before health is judged."""

    def own_problems(self, now: float) -> list[str]:
        """What is wrong that only this kind of device can say."""
        return []

    # -- the same for all --------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self.transport.health.connected

    def write(self, data: bytes) -> bool:
        tr = self.transport
        return tr.health.connected and tr.write(data)

    def handle(self, rec: object) -> None:
        """A record decoded from this device's bytes (the transport's callback)."""
        if isinstance(rec, DeviceError):
            # an error answer is not a reading: counted apart, and shown in health
            self.device_errors += 1
            self.t_device_error = self.host.clock()
            self.last_device_error = rec.what
            if rec.send:
                self.transport.write(rec.send)  # e.g. a Keller that forgot F48 after a blip
            return
        self.records += 1
        self.recent.append(self.host.clock())
        self.on_record(rec)

    async def poll(self, hz: float, request: Callable[[], bytes]) -> None:
        """Ask ``request()`` at ``hz`` on absolute deadlines, while the port is open."""
        period = 1.0 / hz
        while True:
            await pace.sleep_to_next(period, self.host.clock)
            if self.connected:
                self.write(request())

    def recent_bad(self, now: float) -> tuple[int, int]:
        """Bad frames (checksum or content) and skipped bytes in the last ``CORRUPT_WINDOW_S``."""
        stats = self.decoder.stats
        self.bad_history.append((now, stats.bad_checksum + stats.bad_frame, stats.skipped_bytes))
        while len(self.bad_history) > 1 and now - self.bad_history[1][0] >= CORRUPT_WINDOW_S:
            self.bad_history.popleft()
        _, bad0, skipped0 = self.bad_history[0]
        _, bad1, skipped1 = self.bad_history[-1]
        return bad1 - bad0, skipped1 - skipped0

    def health(self, now: float) -> DeviceHealth:
        hl = self.transport.health
        stats = self.decoder.stats
        return DeviceHealth(
            connected=hl.connected,
            last_rx_age_s=None if hl.last_rx is None else round(now - hl.last_rx, 3),
            rate_hz=sum(1 for x in self.recent if now - x <= 5.0) / 5.0,
            records=self.records,
            bad_checksum=stats.bad_checksum,
            bad_frame=stats.bad_frame,
            skipped_bytes=stats.skipped_bytes,
            reconnects=hl.reconnects,
            opens=hl.opens,
            read_errors=hl.read_errors,
            write_errors=hl.write_errors,
            last_error=hl.last_error,
            device_errors=self.device_errors,
            resets=self.resets,
            last_device_error=self.last_device_error,
            info=dict(self.info),
            internal_errors=dict(hl.internal_errors),
            decode_reasons=dict(stats.reasons),
        )

    def sections(self) -> HealthSections:
        """What this device says at health's top level, beside its entry in ``devices``."""
        return {}

    def problems(self, now: float, h: DeviceHealth) -> list[str]:
        """Everything health should say of this device, given its ``health(now)``."""
        n = self.name
        out = [] if h.connected else [f"{n} disconnected"]
        bad, skipped = self.recent_bad(now)
        if bad >= CORRUPT_FRAMES or skipped >= CORRUPT_BYTES:
            out.append(
                f"{n}: {bad} corrupt frames, {skipped} bytes skipped in {CORRUPT_WINDOW_S:g} s"
            )
        expected = self.expected_rate_hz
        age = h.last_rx_age_s
        if expected is not None and age is not None and age > SILENT_S:
            out.append(f"{n}: silent for {age:.0f} s")
        if expected is not None and h.rate_hz > 2.0 * expected + 1.0:
            out.append(f"{n}: {h.rate_hz:.0f} records/s, {expected:g} expected")
        out += self.own_problems(now)
        if self.t_device_error is not None and now - self.t_device_error <= RECENT_S:
            out.append(
                f"{n}: device error answers ({self.device_errors}, last: {self.last_device_error})"
            )
        hl = self.transport.health
        if hl.last_internal_error and now - hl.last_internal_error <= RECENT_S:
            out.append(f"{n}: internal errors {hl.internal_errors}")
        return out
