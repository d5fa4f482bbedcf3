"""Microstrain 3DM-GX3-25 AHRS: its single-byte binary protocol, sans-I/O.

From the 3DM-GX3-25 Single Byte Data Communications Protocol (docs/protocols.md):

* 0xCE Euler angles: a 19-byte answer ``0xCE roll pitch yaw timer checksum``; angles are
  IEEE-754 big-endian floats in radians, the timer a big-endian uint32 of 16 us ticks
  (62.5 kHz), the checksum the big-endian uint16 sum of the 17 bytes before it.
* 0xC4 continuous mode: ``0xC4 0xC1 0x29 <command>`` starts streaming ``<command>``'s
  answer; it is acknowledged with the 8-byte ``0xC4 <command> timer checksum``.
* 0xFA stop continuous mode: ``0xFA 0x75 0xB4``, no answer.
* 0xDB sampling settings: ``0xDB 0xA8 0xB9 <function> <decimation u16> <flags u16>
  <gyro window u8> <mag window u8> <up u16> <north u16> <mag bandwidth u8> 0 0 0 0 0``
  (20 bytes); the device answers ``0xDB`` with the settings and a checksum (19 bytes).
  The data rate is 1000 Hz / decimation.

Yaw is what navd uses: reported in degrees clockwise from magnetic north.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from drivers.codec import FrameDecoder
from navd.records import Attitude

CMD_EULER = 0xCE
CMD_CONTINUOUS = 0xC4
CMD_SAMPLING = 0xDB
TIMER_HZ = 62_500.0
# what the device sends, by its first byte: the 0xCE Euler record and the replies to
# the commands navd sends (set continuous mode, write sampling settings)
_FRAME_LENGTHS = {CMD_EULER: 19, CMD_CONTINUOUS: 8, CMD_SAMPLING: 19}


def checksum(data: bytes) -> int:
    return sum(data) & 0xFFFF


def encode_stop() -> bytes:
    return bytes([0xFA, 0x75, 0xB4])


def encode_continuous(command: int = CMD_EULER) -> bytes:
    return bytes([CMD_CONTINUOUS, 0xC1, 0x29, command])


def encode_sampling(rate_hz: float, function: int = 1) -> bytes:
    """Set (function 1) the data rate; flags 0x0003 stream and enable orientation."""
    decimation = max(1, min(1000, round(1000.0 / rate_hz)))
    return (
        bytes([CMD_SAMPLING, 0xA8, 0xB9, function])
        + struct.pack(">HHBBHHB", decimation, 0x0003, 15, 17, 10, 10, 0)
        + bytes(5)
    )


def encode_euler_poll() -> bytes:
    return bytes([CMD_EULER])


@dataclass(frozen=True, slots=True)
class Ack:
    t: float
    command: int
    timer_s: float | None = None


@dataclass(frozen=True, slots=True)
class Euler:
    """Attitude with the device timer (seconds, wraps every 2^32 ticks)."""

    t: float
    attitude: Attitude
    timer_s: float


class AhrsDecoder(FrameDecoder):
    def _frame_length(self, buf: bytearray) -> int | None:
        return _FRAME_LENGTHS.get(buf[0])

    def _checksum_ok(self, frame: bytes) -> bool:
        return checksum(frame[:-2]) == int.from_bytes(frame[-2:], "big")

    def _parse(self, f: bytes, t: float) -> object | None:
        if f[0] == CMD_EULER:
            roll, pitch, yaw, timer = struct.unpack(">fffI", f[1:17])
            if not all(math.isfinite(v) and abs(v) <= 2 * math.pi for v in (roll, pitch, yaw)):
                self.stats.bad("bad_value")
                return None
            att = Attitude(t, math.degrees(roll), math.degrees(pitch), math.degrees(yaw) % 360.0)
            return Euler(t, att, timer / TIMER_HZ)
        if f[0] == CMD_CONTINUOUS:
            (timer,) = struct.unpack(">I", f[2:6])
            return Ack(t, f[1], timer / TIMER_HZ)
        return Ack(t, f[0])
