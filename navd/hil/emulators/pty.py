"""A pseudo-terminal an emulator serves, behind a stable path that survives reconnects.

The driver opens ``path`` (a symlink to the current /dev/pts/N) with pyserial exactly
as it opens a USB serial adapter.  ``disconnect()`` closes the master side, which
the driver sees as a hang-up; ``reconnect()`` opens a fresh pty behind the same path,
as a re-enumerated USB device would appear again under its udev name.

With a ``baudrate`` the port is a UART: bytes leave at the line's pace (ten bit
times each: start, eight data, stop), so a 53-byte line at 9600 baud takes 55 ms
to arrive, as from the real device.  They are written in slices of a few
milliseconds, the resolution the event loop's timers give.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import time
import tty
from collections.abc import Callable
from pathlib import Path

_SLICE_S = 0.005


class PtyPort:
    def __init__(
        self, path: str | Path, on_bytes: Callable[[bytes], None], baudrate: int | None = None
    ) -> None:
        self.path = Path(path)
        self.on_bytes = on_bytes
        self.byte_s = 10.0 / baudrate if baudrate else 0.0
        self.master: int | None = None
        self._slave: int | None = None
        self._out = bytearray()
        self._drain: asyncio.Task[None] | None = None
        self.open()

    def open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: bytes pass as they are
        os.set_blocking(master, False)
        self.master, self._slave = master, slave
        tmp = self.path.with_name(self.path.name + ".new")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        tmp.symlink_to(os.ttyname(slave))
        tmp.replace(self.path)
        with contextlib.suppress(RuntimeError):
            asyncio.get_running_loop().add_reader(master, self._readable)

    def _readable(self) -> None:
        if self.master is None:
            return
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return  # nobody has the other side open
        if data:
            self.on_bytes(data)

    def write(self, data: bytes) -> None:
        if self.master is None:
            return
        if not self.byte_s:
            self._put(data)
            return
        self._out += data
        if self._drain is None or self._drain.done():
            self._drain = asyncio.get_running_loop().create_task(self._send_paced())

    def _put(self, data: bytes) -> None:
        if self.master is None:
            return
        with contextlib.suppress(BlockingIOError, OSError):
            os.write(self.master, data)

    async def _send_paced(self) -> None:
        per_slice = max(1, int(_SLICE_S / self.byte_s))
        t_free = time.monotonic()
        while self._out:
            chunk = bytes(self._out[:per_slice])
            del self._out[:per_slice]
            self._put(chunk)
            t_free += len(chunk) * self.byte_s
            await asyncio.sleep(max(0.0, t_free - time.monotonic()))

    def disconnect(self) -> None:
        if self.master is None:
            return
        with contextlib.suppress(Exception):
            asyncio.get_running_loop().remove_reader(self.master)
        for fd in (self.master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self._slave = None
        self._out.clear()  # what was on the wire is lost with the cable
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    def reconnect(self) -> None:
        self.disconnect()
        self.open()

    def close(self) -> None:
        self.disconnect()
