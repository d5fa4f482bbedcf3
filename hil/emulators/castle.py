"""Castle Creations controller on its Serial Link: answers register reads."""

from __future__ import annotations

from hil.emulators.base import Emulator


class CastleEmulator(Emulator):
    def __init__(
        self, path, pole_pairs: int = 1, seed: int = 0, baudrate: int | None = None
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.rpm = 0.0  # propeller (mechanical) RPM
        self.pole_pairs = pole_pairs
        self._rx = bytearray()

    def on_bytes(self, data: bytes) -> None:
        self._rx += data
        while len(self._rx) >= 4:
            req = bytes(self._rx[:4])
            if sum(req) & 0xFF:
                del self._rx[0]
                continue
            del self._rx[:4]
            # register 5 is the speed: electrical RPM scaled by 20416.66 / 2042
            raw = round(self.rpm * self.pole_pairs * 2042 / 20416.66) if req[0] == 5 else 0
            raw = max(0, min(0xFFFF, raw))
            body = raw.to_bytes(2, "big")
            self.reply(body + bytes([(-sum(body)) & 0xFF]), delay_s=0.002)
