"""What the emulators share: a pty, injected faults, a clock."""

from __future__ import annotations

import asyncio
import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from navd.hil.emulators.pty import PtyPort


@dataclass(slots=True)
class Faults:
    """Faults on command, each a probability per frame (or a switch)."""

    garbage: float = 0.0  # random bytes before a frame
    bad_checksum: float = 0.0  # one byte of the frame flipped
    truncate: float = 0.0  # the frame cut short
    drop_reply: float = 0.0  # a request never answered
    reply_delay_s: float = 0.0  # extra delay before answering
    stalled: bool = False  # the device says nothing at all
    flood: int = 1  # every frame sent this many times (a babbling device)
    error_reply: float = 0.0  # a command answered with an error (the modem's ERROR)


class Emulator:
    def __init__(self, path: str | Path, seed: int = 0, baudrate: int | None = None) -> None:
        self.faults = Faults()
        self.rng = random.Random(seed)
        self.port = PtyPort(path, self.on_bytes, baudrate)
        self.frames_sent = 0
        self._tasks: list[asyncio.Task[None]] = []

    @property
    def path(self) -> Path:
        return self.port.path

    def now(self) -> float:
        return time.monotonic()

    def on_bytes(self, data: bytes) -> None:  # pragma: no cover - devices override
        pass

    def send(self, frame: bytes) -> None:
        """Put one frame on the line, through whatever faults are switched on."""
        f = self.faults
        if f.stalled:
            return
        out = bytearray(frame)
        if f.bad_checksum and self.rng.random() < f.bad_checksum and out:
            i = self.rng.randrange(len(out))
            out[i] ^= 0x5A
        if f.truncate and self.rng.random() < f.truncate and len(out) > 1:
            del out[self.rng.randrange(1, len(out)) :]
        if f.garbage and self.rng.random() < f.garbage:
            out[0:0] = bytes(self.rng.randrange(256) for _ in range(self.rng.randrange(1, 12)))
        self.frames_sent += 1
        self.port.write(bytes(out) * max(1, f.flood))

    def reply(self, frame: bytes, delay_s: float = 0.0) -> None:
        """Answer a request, late or never if so faulted."""
        if self.faults.drop_reply and self.rng.random() < self.faults.drop_reply:
            return
        delay = delay_s + self.faults.reply_delay_s
        if delay > 0:
            asyncio.get_running_loop().call_later(delay, self.send, frame)
        else:
            self.send(frame)

    def every(self, period_s: float, fn: Callable[[], None]) -> None:
        async def loop() -> None:
            nxt = time.monotonic()
            while True:
                nxt += period_s
                await asyncio.sleep(max(0.0, nxt - time.monotonic()))
                fn()

        self._tasks.append(asyncio.get_running_loop().create_task(loop()))

    def close(self) -> None:
        for t in self._tasks:
            t.cancel()
        self.port.close()
