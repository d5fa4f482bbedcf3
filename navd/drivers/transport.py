"""One asyncio serial transport for every device: pyserial underneath, the codec on top.

A port is a device path or a pyserial URL (``socket://host:port`` for gpsd).

The port is opened non-blocking and watched with the event loop's ``add_reader``;
arriving bytes are stamped with ``time.monotonic()`` and fed to the device's
decoder, whose records go to ``on_record``.  A port that vanishes (USB unplugged,
read error, EOF) is closed, counted and reopened with exponential backoff; the
rest of the daemon never notices beyond the health counters.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import serial

from navd.drivers.codec import Decoder, feed_guarded

log = logging.getLogger(__name__)


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

    # -- lifecycle -------------------------------------------------------------------
    def start(self) -> None:
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
        asyncio.get_running_loop().add_reader(ser.fileno(), self._readable)
        self.health.connected = True
        self.health.opens += 1
        if self.on_open:
            self.on_open(self)

    def _close(self) -> None:
        ser, self._ser = self._ser, None
        self.health.connected = False
        if ser is None:
            return
        with contextlib.suppress(Exception):
            asyncio.get_running_loop().remove_reader(ser.fileno())
        with contextlib.suppress(Exception):
            ser.close()

    # -- I/O -------------------------------------------------------------------------
    def _readable(self) -> None:
        ser = self._ser
        if ser is None:
            return
        try:
            # the loop said the descriptor is readable: read it, without pyserial's own
            # select() before every read (it shows in `bench.daemon_perf --profile`)
            data = os.read(ser.fileno(), 4096)
        except (BlockingIOError, InterruptedError):
            return  # woken with nothing to read after all; the next wake-up reads it
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

    def _internal_error(self, where: str, exc: Exception, t: float) -> None:
        kind = f"{where}: {exc.__class__.__name__}"
        n = self.health.internal_errors.get(kind, 0)
        self.health.internal_errors[kind] = n + 1
        self.health.last_internal_error = t
        if n == 0:  # once per kind: a repeating bug must not flood the journal
            log.error("%s: %s raised (counted in health)", self.port, kind, exc_info=exc)

    def _lose(self) -> None:
        ser = self._ser
        if ser is not None:
            with contextlib.suppress(Exception):
                asyncio.get_running_loop().remove_reader(ser.fileno())
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
