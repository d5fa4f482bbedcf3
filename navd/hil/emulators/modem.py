"""Benthos ATM-903 with a UDB-9400 at the far end: AT commands, ranging with location.

It prints what the ATM-900 prints (docs/protocols.md, "Benthos"): the range line
with its round trip and relative speed, ``Response Not Received.`` after its own
timeout, ``ERROR`` for a command it cannot run now, and its shell's
``Command '...' not found`` for one it does not know.  Like the modem after power-up
it starts online (data mode), where commands are data: ``+++`` after at least one
second of silence brings its shell (``user:1>``), ``ATO`` or ``go_online()`` (a
``CONNECT``) takes it back online.

``range_to(t)`` is supplied by whoever drives the emulator (the world simulator, or a
test): given the time of the ping it returns ``(round_trip_s, range_m, lat, lon, depth)``
of the deck box, or None when the ping is lost.  The answer is sent after the true
round trip, as the modem prints it when the reply arrives.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path

from navd.hil.emulators.base import Emulator

GUARD_S = 1.0  # the silence the modem demands before +++
RangeFn = Callable[[float], tuple[float, float, float | None, float | None, float | None] | None]


class ModemEmulator(Emulator):
    def __init__(
        self,
        path: str | Path,
        range_to: RangeFn,
        own_addr: int = 1,
        seed: int = 0,
        timeout_s: float = 4.0,
        baudrate: int | None = None,
        sound_speed_mps: float = 1500.0,
        online: bool = True,
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.online = online
        self._t_rx = -1e9  # when the last byte came: the escape needs silence before it
        self.sound_speed_mps = sound_speed_mps  # the modem's setting: range = c * round trip / 2
        self.range_to = range_to
        self.own_addr = own_addr
        self.timeout_s = timeout_s
        self.corrupt_position = 0.0  # probability a location line arrives garbled
        self.busy = False
        self._rx = bytearray()

    def go_online(self) -> None:
        self.online = True
        self.send(b"CONNECT 2400\r\n")

    def on_bytes(self, data: bytes) -> None:
        now = self.now()
        silence, self._t_rx = now - self._t_rx, now
        if self.online:
            if silence >= GUARD_S:
                self._rx.clear()  # an escape counts only after the guard time
            self._rx += data
            if self._rx.startswith(b"+++"):
                self.online = False
                del self._rx[:3]
                self.reply(b"\r\nuser:1> ")
            elif not b"+++".startswith(bytes(self._rx[:3])):
                self._rx.clear()  # data for the acoustic link
            return
        self._rx += data
        while True:
            i = self._rx.find(b"\r")
            if i < 0:
                if len(self._rx) > 256:
                    self._rx.clear()
                return
            line = bytes(self._rx[:i]).strip().decode("ascii", "replace").upper()
            del self._rx[: i + 1]
            self._command(line)

    def _command(self, line: str) -> None:
        if not line:
            return
        if line == "AT":
            self.reply(b"OK\r\n")
        elif line == "ATO":
            self.go_online()
        elif self.faults.error_reply and self.rng.random() < self.faults.error_reply:
            self.reply(b"ERROR\r\n")
        elif line.startswith("ATRX") or line.startswith("ATR"):
            digits = line[4:] if line.startswith("ATRX") else line[3:]
            if not digits.isdigit() or self.busy:
                self.reply(b"ERROR\r\n")
                return
            self._ping(int(digits))
        else:
            self.reply(f"Command '{line}' not found\r\n".encode("ascii", "replace"))

    def _ping(self, remote: int) -> None:
        self.busy = True
        res = self.range_to(self.now())
        if res is None:
            self.reply(b"Response Not Received.\r\n", delay_s=self.timeout_s)
            self._free_after(self.timeout_s)
            return
        rtt, rng, lat, lon, depth = res
        loc = ""
        if lat is not None and lon is not None:  # the deck box may send no position
            loc = f"Remote Lat: {lat:.7f} Lon: {lon:.7f} Depth: {depth or 0.0:.1f}\r\n"
            if self.corrupt_position and self.rng.random() < self.corrupt_position:
                loc = loc.replace(".", "", 1)  # a dropped character garbles the latitude
        # the round trip it prints is the one its range comes from (the answer itself
        # arrives after the physical round trip, ``rtt``)
        measured_ms = 2000.0 * rng / self.sound_speed_mps
        text = (
            f"Range {self.own_addr} to {remote} : {rng:.1f} m  "
            f"(Round-trip  {measured_ms:.1f} ms) speed  0.0 m/s\r\n{loc}OK\r\n"
        )
        self.reply(text.encode("ascii"), delay_s=rtt)
        self._free_after(rtt)

    def _free_after(self, s: float) -> None:
        def free() -> None:
            self.busy = False

        asyncio.get_running_loop().call_later(s, free)
