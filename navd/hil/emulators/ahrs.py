"""Microstrain 3DM-GX3-25: answers polls, streams Euler angles in continuous mode.

As the single-byte protocol (DCP v1.14) describes the device: a command whose
confirmation bytes are wrong is answered ``21 00 21``; 0xE9 gives the firmware
version.  ``mip=True`` makes it a 2.x firmware unit instead, which speaks only MIP
and answers single-byte commands with nothing.
"""

from __future__ import annotations

import asyncio
import math
import struct
import time
from pathlib import Path

from navd.hil.emulators.base import Emulator

REFUSED = bytes([0x21, 0x00, 0x21])  # wrong confirmation bytes
#: the commands the emulated unit knows, by first byte, and their length in bytes
_COMMAND_BYTES = {0xE9: 1, 0xE5: 4, 0xFE: 3, 0xCE: 1, 0xC4: 4, 0xFA: 3, 0xDB: 20}


def _with_sum(body: bytes) -> bytes:
    return body + struct.pack(">H", sum(body) & 0xFFFF)


class AhrsEmulator(Emulator):
    def __init__(
        self,
        path: str | Path,
        seed: int = 0,
        baudrate: int | None = None,
        firmware: int = 1134,
        mip: bool = False,
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.firmware = firmware
        self.mip = mip
        self.hard_iron = (0.0, 0.0, 0.0)  # as shipped: never calibrated
        self.resets = 0
        self.roll_deg = 0.0
        self.pitch_deg = 0.0
        self.yaw_deg = 0.0  # magnetic, as the device reports
        self.decimation = 10  # 100 Hz until told otherwise
        self.streaming = False
        self._t0 = time.monotonic()
        self._rx = bytearray()
        self._stream_task: asyncio.Task[None] | None = None

    def _timer(self) -> int:
        return int((time.monotonic() - self._t0) * 62_500) & 0xFFFFFFFF

    def euler_frame(self) -> bytes:
        yaw = math.radians(self.yaw_deg)
        if yaw > math.pi:
            yaw -= 2 * math.pi  # the device reports yaw in [-pi, pi]
        body = bytes([0xCE]) + struct.pack(
            ">fffI", math.radians(self.roll_deg), math.radians(self.pitch_deg), yaw, self._timer()
        )
        return _with_sum(body)

    def on_bytes(self, data: bytes) -> None:
        if self.mip:
            return  # a MIP unit does not know these commands
        self._rx += data
        while self._rx:
            n = _COMMAND_BYTES.get(self._rx[0])
            if n is None:
                del self._rx[0]  # not a command the device knows: ignored
                continue
            if len(self._rx) < n:
                return
            cmd = bytes(self._rx[:n])
            del self._rx[:n]
            self._command(cmd)

    def _command(self, cmd: bytes) -> None:
        c = cmd[0]
        if c == 0xE9:
            self.reply(_with_sum(bytes([0xE9]) + struct.pack(">I", self.firmware)))
        elif c == 0xE5:
            word = self._eeprom(int.from_bytes(cmd[2:4], "big"))
            self.reply(_with_sum(bytes([0xE5]) + word.to_bytes(2, "big")))
        elif c == 0xFE and cmd == b"\xfe\x9e\x3a":  # soft reset: the stored settings again
            self.resets += 1
            self.streaming = False
            self.decimation = 10
        elif c == 0xCE:
            self.reply(self.euler_frame())
        elif c == 0xC4 and cmd[1:3] == b"\xc1\x29":
            self.reply(_with_sum(bytes([0xC4, cmd[3]]) + struct.pack(">I", self._timer())))
            self._start_stream()
        elif c == 0xFA:
            self.streaming = False
        elif c == 0xDB and cmd[1:3] == b"\xa8\xb9":
            if cmd[3] == 1:
                self.decimation = max(1, struct.unpack(">H", cmd[4:6])[0])
            self.reply(_with_sum(bytes([0xDB]) + cmd[4:20]))
        else:
            self.reply(REFUSED)  # a known command with arguments the device refuses

    def _eeprom(self, address: int) -> int:
        base = 0x0400
        i = address - base
        if not (0 <= i < 12 and i % 2 == 0):
            return 0
        bits = int.from_bytes(struct.pack(">f", self.hard_iron[i // 4]), "big")
        return bits & 0xFFFF if i % 4 == 0 else bits >> 16  # the low word first

    @property
    def rate_hz(self) -> float:
        return 1000.0 / self.decimation

    def _start_stream(self) -> None:
        self.streaming = True
        if self._stream_task is None:
            self.every(1.0 / self.rate_hz, self._tick)
            self._stream_task = self._tasks[-1]

    def _tick(self) -> None:
        if self.streaming:
            self.send(self.euler_frame())
