"""Castle Creations motor controller: propeller RPM over the Castle Serial Link, sans-I/O.

The Serial Link answers register reads (docs/protocols.md, "Castle"): a request is
four bytes ``register 0x00 0x00 check`` and the answer three bytes ``value_hi value_lo
check``; each check byte makes its frame sum to zero modulo 256.  Register 5 is the
electrical speed: eRPM = raw / 2042 * 20416.66; the propeller turns at eRPM divided by
the motor's pole pairs.  Answers carry no header, so they are matched to requests in
order, and a frame whose check fails is slid over byte by byte.
"""

from __future__ import annotations

from collections import deque

from drivers.codec import DecodeStats
from navd.records import Rpm

REG_SPEED = 5
SPEED_SCALE = 20416.66
_RAW_FULL = 2042.0


def check_byte(data: bytes) -> int:
    return (-sum(data)) & 0xFF


def encode_read(register: int) -> bytes:
    body = bytes([register, 0, 0])
    return body + bytes([check_byte(body)])


class CastleDecoder:
    def __init__(self, pole_pairs: int = 1, max_rpm: float = 20_000.0) -> None:
        self.pole_pairs = pole_pairs
        # Answers have no header and a one-byte check: after line noise, one window in 256
        # passes the check by chance.  A propeller speed no motor can reach marks it.
        self.max_rpm = max_rpm
        self.stats = DecodeStats()
        self._buf = bytearray()
        self._pending: deque[int] = deque(maxlen=8)

    def request_rpm(self) -> bytes:
        self._pending.append(REG_SPEED)
        return encode_read(REG_SPEED)

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
            rpm = raw / _RAW_FULL * SPEED_SCALE / self.pole_pairs
            if self._pending[0] == REG_SPEED and rpm > self.max_rpm:
                # a window that passed the check by chance, not an answer: slide over it
                # like a bad check, and keep the request waiting for its real answer
                self.stats.bad_frame += 1
                self.stats.skip(1, "implausible")
                del self._buf[0]
                continue
            del self._buf[:3]
            if self._pending.popleft() == REG_SPEED:
                out.append(Rpm(t, rpm))
                self.stats.records += 1
        return out
