"""Keller PA-30X on its RS-485 bus: answers F48 and F73 addressed to it.

``status`` is the status byte every F73 answer carries (*Communication protocol Serie
30* v2.2, section 4.8): set bit 1 (0x02) for a P1 measuring error, bit 4 (0x10) for
a TOB1 error.  After ``power_blip()`` the device answers every read with exception
32 (not initialised) until it gets F48 again.  ``local_echo`` plays an RS-485 adapter
that hands every request back (LSTS DUNE, Sensors/Keller).
"""

from __future__ import annotations

import struct
from pathlib import Path

from navd.hil.emulators.base import Emulator


def _crc(data: bytes) -> bytes:
    # Keller bus CRC-16 (polynomial 0x8005 reflected = 0xA001, start 0xFFFF), high byte first
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            lsb = crc & 1
            crc >>= 1
            if lsb:
                crc ^= 0xA001
    return bytes([crc >> 8, crc & 0xFF])


class KellerEmulator(Emulator):
    def __init__(
        self,
        path: str | Path,
        addr: int = 250,
        seed: int = 0,
        baudrate: int | None = None,
        local_echo: bool = False,
        serial_number: int = 123456,
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.addr = addr
        self.local_echo = local_echo
        self.serial_number = serial_number
        self.initialised = True
        self.pressure_bar = 1.01325
        self.temperature_c = 12.0
        self.status = 0
        self._rx = bytearray()

    def power_blip(self) -> None:
        self.initialised = False

    def on_bytes(self, data: bytes) -> None:
        if self.local_echo:
            self.port.write(data)  # the adapter, not the sensor: no faults apply
        self._rx += data
        while len(self._rx) >= 4:
            if self._rx[0] != self.addr and self._rx[0] != 250:
                del self._rx[0]
                continue
            fn = self._rx[1]
            n = 5 if fn == 73 else 4
            if len(self._rx) < n:
                return
            req = bytes(self._rx[:n])
            if _crc(req[:-2]) != req[-2:]:
                del self._rx[0]
                continue
            del self._rx[:n]
            self._answer(fn, req)

    def _answer(self, fn: int, req: bytes) -> None:
        if fn == 48:
            self.initialised = True
            body = bytes([self.addr, 48, 5, 20, 16, 10, 0, 0])  # class 5, group 20, 2016 wk 10
        elif not self.initialised:
            body = bytes([self.addr, fn | 0x80, 32])  # exception 32: not initialised
        elif fn == 69:
            body = bytes([self.addr, 69]) + self.serial_number.to_bytes(4, "big")
        elif fn == 73:
            channel = req[2]
            if channel == 1:
                value = self.pressure_bar
            elif channel == 4:
                value = self.temperature_c
            else:
                body = bytes([self.addr, 73 | 0x80, 2])  # exception 2: invalid channel
                self.reply(body + _crc(body))
                return
            body = bytes([self.addr, 73]) + struct.pack(">f", value) + bytes([self.status])
        else:
            body = bytes([self.addr, fn | 0x80, 1])  # exception 1: unknown function
        self.reply(body + _crc(body), delay_s=0.005)
