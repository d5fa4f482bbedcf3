"""Castle Creations controller on its Serial Link: answers register reads.

As the Serial Link protocol (v1.5) describes the controller: a request is five bytes
``0x80 | id, register, data_hi, data_lo, check``; a frame starts only at a byte with
bit 7 set, so the five ``00`` bytes a host sends to clear the buffer are passed over;
a frame whose check fails, or addressed to another id, is discarded whole and not
answered; a register the controller does not have is answered ``FF FF`` (its error
answer).
"""

from __future__ import annotations

from pathlib import Path

from navd.hil.emulators.base import Emulator

_RAW_FULL = 2042.0
# the registers emulated, and their scale (value = raw / 2042 * scale); the others
# get the error answer
_SCALE = {0: 20.0, 2: 50.0, 5: 20416.66, 6: 30.0}


class CastleEmulator(Emulator):
    def __init__(
        self,
        path: str | Path,
        pole_pairs: int = 1,
        seed: int = 0,
        baudrate: int | None = None,
        device_id: int = 0,
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.rpm = 0.0  # propeller (mechanical) RPM
        self.pole_pairs = pole_pairs
        self.device_id = device_id
        self.battery_v = 14.8
        self.current_a = 3.0
        self.temperature_c = 25.0
        self.requests_refused = 0  # discarded frames (bad check, other id): what a test can see
        self._rx = bytearray()

    def _value(self, register: int) -> float:
        return {
            0: self.battery_v,
            2: self.current_a,
            5: self.rpm * self.pole_pairs,  # electrical RPM
            6: self.temperature_c,
        }.get(register, 0.0)

    def on_bytes(self, data: bytes) -> None:
        self._rx += data
        while self._rx:
            if not self._rx[0] & 0x80:
                del self._rx[0]  # not a frame start: a clearing 00 or noise
                continue
            if len(self._rx) < 5:
                return
            req = bytes(self._rx[:5])
            del self._rx[:5]
            if sum(req) & 0xFF or req[0] & 0x7F != self.device_id:
                self.requests_refused += 1
                continue
            register = req[1]
            if register in _SCALE and not (
                self.faults.error_reply and self.rng.random() < self.faults.error_reply
            ):
                raw = round(self._value(register) / _SCALE[register] * _RAW_FULL)
                raw = max(0, min(0xFFFE, raw))
            else:
                raw = 0xFFFF
            body = raw.to_bytes(2, "big")
            self.reply(body + bytes([(-sum(body)) & 0xFF]), delay_s=0.002)
