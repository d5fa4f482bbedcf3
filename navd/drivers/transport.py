"""One asyncio serial transport for every device: pyserial underneath, the codec on top.

A port is a device path or a pyserial URL (``socket://host:port`` for gpsd).

The port is opened non-blocking and read every ``read_window_s`` (50 ms), on a grid
of the event loop's clock that every port shares, so the daemon's five ports are
read in one wake-up, and the daemon's other timers fall on the same grid
(navd/daemon/pace.py).  Watching each descriptor with ``add_reader`` instead woke the
loop for every few bytes a UART hands over (a 4800-baud GPS some 120 times a
second), and each wake-up cost more than its bytes.  Bytes wait in the kernel's
buffer meanwhile, so none is lost, and a record is stamped at most 50 ms late (8 cm
of a vehicle's travel at 1.5 m/s, against ranges good to metres); the filter's tick
is two windows, so what arrived before a tick is read before it.  Arriving bytes
are stamped with ``time.monotonic()`` and fed to the device's decoder, whose
records go to ``on_record``.  A port that vanishes (USB unplugged,
read error, EOF) is closed, counted and reopened with exponential backoff; the
rest of the daemon never notices beyond the health counters.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import select
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from navd.drivers.codec import Decoder, feed_guarded

log = logging.getLogger(__name__)

READ_WINDOW_S = 0.05
_READ_MAX = 1 << 16  # more than 50 ms of any serial line; a socket's backlog is read in turns


class _Reader:
    """The open ports of one event loop, polled together every ``window`` seconds on
    the loop clock's grid: one timer and one ``poll`` for all of them."""

    def __init__(self, window: float) -> None:
        # no reference to the loop: it is the key this reader is kept under (weakly)
        self.window = window
        self.poll = select.poll()
        self.ports: dict[int, Callable[[], None]] = {}
        self.handle: asyncio.TimerHandle | None = None
        self.reported: set[int] = set()

    def add(self, fd: int, on_ready: Callable[[], None]) -> None:
        # readable, or hung up: a tty opened for non-blocking reads answers an empty
        # read for both, and only the second is the end of the port
        self.poll.register(fd, select.POLLIN | select.POLLPRI)
        self.ports[fd] = on_ready
        if self.handle is None:
            self._schedule()

    def remove(self, fd: int) -> None:
        if self.ports.pop(fd, None) is None:
            return
        with contextlib.suppress(KeyError, ValueError):
            self.poll.unregister(fd)
        if not self.ports and self.handle is not None:
            self.handle.cancel()
            self.handle = None

    def _schedule(self) -> None:
        loop = asyncio.get_running_loop()
        when = (math.floor(loop.time() / self.window) + 1.0) * self.window
        self.handle = loop.call_at(when, self._tick)

    def _tick(self) -> None:
        self.handle = None
        try:
            for fd, _events in self.poll.poll(0):
                on_ready = self.ports.get(fd)
                if on_ready is None:
                    continue  # removed by a port read before it
                try:
                    on_ready()
                except Exception:  # one port's fault must not stop the others' reads
                    if fd not in self.reported:  # once: it would repeat every window
                        self.reported.add(fd)
                        log.exception("reading fd %d raised", fd)
        finally:
            if self.ports and self.handle is None:
                self._schedule()


_readers: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, dict[float, _Reader]] = (
    weakref.WeakKeyDictionary()
)


def _reader(window: float) -> _Reader:
    by_window = _readers.setdefault(asyncio.get_running_loop(), {})
    r = by_window.get(window)
    if r is None:
        r = by_window[window] = _Reader(window)
    return r


@dataclass(slots=True)
class PortHealth:
    connected: bool = False
    opens: int = 0
    reconnects: int = 0
    read_errors: int = 0
    write_errors: int = 0
    last_rx: float | None = None  # monotonic time of the last byte
    last_record: float | None = None
    last_error: str = ""
    # exceptions raised by the decoder or the record handler, by kind; each is caught
    # so the rest of the chunk is still delivered (a bug must not lose a port)
    internal_errors: dict[str, int] = field(default_factory=dict)
    last_internal_error: float | None = None


class SerialTransport:
    def __init__(
        self,
        port: str,
        baudrate: int,
        decoder: Decoder,
        on_record: Callable[[object], None],
        on_open: Callable[[SerialTransport], None] | None = None,
        backoff_s: tuple[float, float] = (0.1, 5.0),
        clock: Callable[[], float] = time.monotonic,
        read_window_s: float = READ_WINDOW_S,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.decoder = decoder
        self.on_record = on_record
        self.on_open = on_open
        self.backoff = backoff_s
        self.clock = clock
        self.health = PortHealth()
        self._ser: serial.Serial | None = None
        self._lost: asyncio.Event = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self.read_window_s = read_window_s
        self._fd: int | None = None

    # -- lifecycle -------------------------------------------------------------------
    def start(self) -> None:
        self._reader = _reader(max(self.read_window_s, 1e-3))
        self._task = asyncio.get_running_loop().create_task(self._run(), name=f"serial {self.port}")

    async def stop(self) -> None:
        if self._task:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        self._close()

    async def _run(self) -> None:
        delay = self.backoff[0]
        while True:
            try:
                self._open()
            except (serial.SerialException, OSError) as exc:
                self.health.last_error = f"open: {exc}"
                await asyncio.sleep(delay)
                delay = min(self.backoff[1], delay * 2)
                continue
            delay = self.backoff[0]
            await self._lost.wait()
            self._close()
            self.health.reconnects += 1
            log.warning("%s: port lost (%s), reopening", self.port, self.health.last_error)

    def _open(self) -> None:
        # a device path, or a URL such as socket://127.0.0.1:2947 (gpsd): pyserial's
        # socket handler is read through the same non-blocking file descriptor
        ser = serial.serial_for_url(self.port, self.baudrate, timeout=0, write_timeout=0)
        self._ser = ser
        self._lost = asyncio.Event()
        self._fd = ser.fileno()
        self._reader.add(self._fd, self._read)
        self.health.connected = True
        self.health.opens += 1
        if self.on_open:
            self.on_open(self)

    def _close(self) -> None:
        self._unwatch()
        ser, self._ser = self._ser, None
        self.health.connected = False
        if ser is None:
            return
        with contextlib.suppress(Exception):
            ser.close()

    # -- I/O -------------------------------------------------------------------------
    def _read(self) -> None:
        ser = self._ser
        if ser is None:
            return
        try:
            # straight from the descriptor, without pyserial's own select() before
            # every read (it shows in `bench.daemon_perf --profile`)
            data = os.read(ser.fileno(), _READ_MAX)
        except (BlockingIOError, InterruptedError):
            return  # polled readable with nothing to read after all
        except (serial.SerialException, OSError) as exc:
            self.health.read_errors += 1
            self.health.last_error = f"read: {exc}"
            self._lose()
            return
        if not data:
            # readable with nothing to read: the other end hung up
            self.health.last_error = "read: end of file"
            self._lose()
            return
        t = self.clock()
        self.health.last_rx = t
        records = feed_guarded(
            self.decoder, data, t, lambda exc: self._internal_error("decoder", exc, t)
        )
        for rec in records:
            self.health.last_record = t
            try:
                self.on_record(rec)
            except Exception as exc:  # the handler's bug must not cost the chunk's other records
                self._internal_error("handler", exc, t)

    def _unwatch(self) -> None:
        if self._fd is not None:
            self._reader.remove(self._fd)
            self._fd = None

    def _internal_error(self, where: str, exc: Exception, t: float) -> None:
        kind = f"{where}: {exc.__class__.__name__}"
        n = self.health.internal_errors.get(kind, 0)
        self.health.internal_errors[kind] = n + 1
        self.health.last_internal_error = t
        if n == 0:  # once per kind: a repeating bug must not flood the journal
            log.error("%s: %s raised (counted in health)", self.port, kind, exc_info=exc)

    def _lose(self) -> None:
        self._unwatch()
        self.health.connected = False
        self._lost.set()

    def write(self, data: bytes) -> bool:
        """Send bytes now; False (and counted) if the port is down or the write fails."""
        ser = self._ser
        if ser is None:
            self.health.write_errors += 1
            return False
        try:
            ser.write(data)
        except (serial.SerialException, OSError) as exc:
            self.health.write_errors += 1
            self.health.last_error = f"write: {exc}"
            self._lose()
            return False
        return True
