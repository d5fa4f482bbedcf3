"""Castle Creations motor controller: propeller RPM and ESC status, sans-I/O.

Castle Creations, *Castle Serial Link Communication Protocol* v1.5 (docs/protocols.md,
"Castle"; dgatf/castle_telemetry implements the same frames):

* A request is five bytes ``0x80 | device_id, register, data_hi, data_lo, check``; the
  check byte makes the five sum to zero modulo 256.  Device 0, register 5 is
  ``80 05 00 00 7B``.
* The answer is three bytes ``value_hi value_lo check`` with the same rule.  It has no
  header, so one request is open at a time and the answer is matched to it; a window
  whose check fails is slid over byte by byte.  ``0xFFFF`` is the controller's error
  answer.
* Five ``00`` bytes clear the controller's command buffer (a half request left there
  by a reset or line noise would swallow the first real one): sent on every open.
* A register's value is ``raw / 2042 * scale``: 0 battery volts (scale 20), 2 current
  in amperes (50), 5 electrical RPM (20416.66), 6 temperature in degrees C (30).  The
  propeller turns at the electrical RPM divided by the motor's pole pairs.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from navd.drivers.codec import DecodeStats, DeviceError
from navd.records import Rpm

REG_VOLTAGE = 0
REG_CURRENT = 2
REG_SPEED = 5
REG_TEMPERATURE = 6
_RAW_FULL = 2042.0
SCALE = {REG_VOLTAGE: 20.0, REG_CURRENT: 50.0, REG_SPEED: 20416.66, REG_TEMPERATURE: 30.0}
# the status registers, with the name health gives them
STATUS = {REG_VOLTAGE: "battery_v", REG_CURRENT: "current_a", REG_TEMPERATURE: "temperature_c"}
ERROR_ANSWER = 0xFFFF
CLEAR = bytes(5)
# one status register in this many polls: at 10 Hz each is read every 3 s
STATUS_EVERY = 10


def check_byte(data: bytes) -> int:
    return (-sum(data)) & 0xFF


def encode_read(register: int, device_id: int = 0) -> bytes:
    body = bytes([0x80 | (device_id & 0x7F), register, 0, 0])
    return body + bytes([check_byte(body)])


def value_of(register: int, raw: int) -> float:
    return raw / _RAW_FULL * SCALE.get(register, 1.0)


@dataclass(frozen=True, slots=True)
class EscStatus:
    """One status reading of the controller (battery voltage, current, temperature)."""

    t: float
    name: str
    value: float


class CastleDecoder:
    def __init__(self, pole_pairs: int = 1, device_id: int = 0, max_rpm: float = 20_000.0) -> None:
        self.pole_pairs = pole_pairs
        self.device_id = device_id
        # Answers have no header and a one-byte check: after line noise, one window in 256
        # passes the check by chance.  A propeller speed no motor can reach marks it.
        self.max_rpm = max_rpm
        self.stats = DecodeStats()
        self._buf = bytearray()
        self._pending: deque[int] = deque(maxlen=1)
        self._polls = 0

    def request_clear(self) -> bytes:
        self._pending.clear()
        self._buf.clear()
        return CLEAR

    def request(self, register: int) -> bytes:
        if self._pending:
            # The controller answers within milliseconds, far inside a poll period: a
            # request still open now was lost.  Matching later answers to it would read
            # every answer as the register asked one poll before (a voltage as a speed).
            self.stats.reasons["unanswered"] = self.stats.reasons.get("unanswered", 0) + 1
            self._pending.clear()
            self._buf.clear()
        self._pending.append(register)
        return encode_read(register, self.device_id)

    def request_rpm(self) -> bytes:
        return self.request(REG_SPEED)

    def request_poll(self) -> bytes:
        """The speed, and now and then one status register in its place."""
        self._polls += 1
        if self._polls % STATUS_EVERY:
            return self.request(REG_SPEED)
        regs = list(STATUS)
        return self.request(regs[(self._polls // STATUS_EVERY) % len(regs)])

    def reset(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        self._buf += data
        out: list[object] = []
        while len(self._buf) >= 3:
            if not self._pending:
                self.stats.skip(len(self._buf), "unsolicited")
                self._buf.clear()
                break
            frame = bytes(self._buf[:3])
            if sum(frame) & 0xFF:
                self.stats.bad_checksum += 1
                self.stats.skip(1, "checksum")
                del self._buf[0]
                continue
            raw = int.from_bytes(frame[:2], "big")
            register = self._pending[0]
            if raw == ERROR_ANSWER:
                del self._buf[:3]
                self._pending.popleft()
                self.stats.records += 1
                out.append(DeviceError(t, register, f"error answer to register {register}"))
                continue
            rpm = value_of(REG_SPEED, raw) / self.pole_pairs
            if register == REG_SPEED and rpm > self.max_rpm:
                # a window that passed the check by chance, not an answer: slide over it
                # like a bad check, and keep the request waiting for its real answer
                self.stats.bad_frame += 1
                self.stats.skip(1, "implausible")
                del self._buf[0]
                continue
            del self._buf[:3]
            self._pending.popleft()
            self.stats.records += 1
            if register == REG_SPEED:
                out.append(Rpm(t, rpm))
            elif register in STATUS:
                out.append(EscStatus(t, STATUS[register], value_of(register, raw)))
        return out
