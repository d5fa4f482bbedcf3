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
  The data rate is 1000 Hz / decimation.  Flag bit 0 enables the orientation
  computation, bit 1 coning and sculling compensation.
* 0xE9 firmware version: answered ``0xE9 <version u32> checksum`` (7 bytes; LSTS DUNE
  probes the device with it).  navd sends it on every open.
* ``21 00 21``: the device refuses a command whose confirmation bytes are wrong.
* 0xE5 read an EEPROM word: ``E5 00 addr_hi addr_lo``, answered ``E5 value(u16)
  checksum`` (5 bytes).  The hard-iron offsets are three float32 from 0x0400 (six
  words; LSTS DUNE reads and writes them there).
* ``FE 9E 3A`` soft reset: no answer; the device restarts with its stored settings.

Units with 2.x firmware speak MIP instead (frames ``75 65 <set> <length> ...
<Fletcher-16>``): they are recognised, counted, and refused as a device error.

Yaw is what navd uses: reported in degrees clockwise from magnetic north.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from dataclasses import dataclass

from navd.drivers.codec import DeviceError, FrameDecoder
from navd.records import Attitude

CMD_EULER = 0xCE
CMD_CONTINUOUS = 0xC4
CMD_SAMPLING = 0xDB
CMD_FIRMWARE = 0xE9
CMD_READ_EEPROM = 0xE5
#: the hard-iron offsets: three float32 from this EEPROM address, in 6 words, low word first
HARD_IRON_ADDR = 0x0400
REFUSED = bytes([0x21, 0x00, 0x21])
MIP_SYNC = bytes([0x75, 0x65])
TIMER_HZ = 62_500.0
# orientation (bit 0) with coning and sculling compensation (bit 1)
_SAMPLING_FLAGS = 0x0003
# what the device sends, by its first byte: the 0xCE Euler record and the replies to
# the commands navd sends (set continuous mode, write sampling settings, firmware)
_FRAME_LENGTHS = {
    CMD_EULER: 19,
    CMD_CONTINUOUS: 8,
    CMD_SAMPLING: 19,
    CMD_FIRMWARE: 7,
    CMD_READ_EEPROM: 5,
}


def checksum(data: bytes) -> int:
    return sum(data) & 0xFFFF


def encode_stop() -> bytes:
    return bytes([0xFA, 0x75, 0xB4])


def encode_continuous(command: int = CMD_EULER) -> bytes:
    return bytes([CMD_CONTINUOUS, 0xC1, 0x29, command])


def encode_sampling(rate_hz: float, function: int = 1) -> bytes:
    """Set (function 1) the data rate, with orientation and coning/sculling compensation."""
    decimation = max(1, min(1000, round(1000.0 / rate_hz)))
    return (
        bytes([CMD_SAMPLING, 0xA8, 0xB9, function])
        + struct.pack(">HHBBHHB", decimation, _SAMPLING_FLAGS, 15, 17, 10, 10, 0)
        + bytes(5)
    )


def encode_firmware_probe() -> bytes:
    return bytes([CMD_FIRMWARE])


def encode_soft_reset() -> bytes:
    return bytes([0xFE, 0x9E, 0x3A])


def encode_read_eeprom(address: int) -> bytes:
    return bytes([CMD_READ_EEPROM, 0x00]) + address.to_bytes(2, "big")


def hard_iron(words: list[int]) -> tuple[float, float, float]:
    """The three hard-iron offsets from the six EEPROM words that hold them.

    Each float32 is two words, its low 16 bits at the lower address: the order LSTS
    DUNE's 3DM-GX3 task writes them in (``setHardIron``: ``val & 0xffff`` to
    ``m_addr[2i]``, ``val >> 16`` to ``m_addr[2i+1]``) and reads them back
    (``hard_iron[2i+1] << 16 | hard_iron[2i]``), on units in the field.
    """
    raw = b"".join(
        words[i + 1].to_bytes(2, "big") + words[i].to_bytes(2, "big") for i in (0, 2, 4)
    )
    x, y, z = struct.unpack(">fff", raw)
    return x, y, z


def fletcher16(data: bytes) -> bytes:
    """MIP's checksum (two running byte sums)."""
    a = b = 0
    for x in data:
        a = (a + x) & 0xFF
        b = (b + a) & 0xFF
    return bytes([a, b])


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


@dataclass(frozen=True, slots=True)
class EepromWord:
    t: float
    address: int
    value: int


@dataclass(frozen=True, slots=True)
class Firmware:
    t: float
    version: int  # e.g. 1134 for 1.1.34


MIP_ERROR = 0x7565  # the DeviceError code of a MIP frame


class AhrsDecoder(FrameDecoder):
    def __init__(self) -> None:
        super().__init__()
        # EEPROM answers carry no address: matched to the reads in order
        self._eeprom: deque[int] = deque(maxlen=16)

    def request_eeprom(self, address: int) -> bytes:
        self._eeprom.append(address)
        return encode_read_eeprom(address)

    def request_hard_iron(self) -> bytes:
        # a new read of all six supersedes reads never answered (a unit that was silent):
        # left queued they would pair the next answers with the wrong addresses
        self._eeprom.clear()
        return b"".join(self.request_eeprom(HARD_IRON_ADDR + 2 * i) for i in range(6))

    def _frame_length(self, buf: bytearray) -> int | None:
        if buf[0] == REFUSED[0]:
            return len(REFUSED) if buf[1:2] in (b"", REFUSED[1:2]) else None
        if buf[0] == MIP_SYNC[0]:
            if len(buf) < 4:
                return 0 if buf[1:2] in (b"", MIP_SYNC[1:]) else None
            return 6 + buf[3] if buf[1] == MIP_SYNC[1] else None
        return _FRAME_LENGTHS.get(buf[0])

    def _checksum_ok(self, frame: bytes) -> bool:
        if frame[0] == REFUSED[0]:
            return frame == REFUSED
        if frame[:2] == MIP_SYNC:
            return fletcher16(frame[:-2]) == frame[-2:]
        return checksum(frame[:-2]) == int.from_bytes(frame[-2:], "big")

    def _parse(self, f: bytes, t: float) -> object | None:
        if f == REFUSED:
            return DeviceError(t, REFUSED[0], "refused a command (wrong confirmation bytes)")
        if f[:2] == MIP_SYNC:
            return DeviceError(
                t,
                MIP_ERROR,
                "speaks MIP (a 2.x firmware unit): navd needs the single-byte protocol",
            )
        if f[0] == CMD_FIRMWARE:
            return Firmware(t, int.from_bytes(f[1:5], "big"))
        if f[0] == CMD_READ_EEPROM:
            if not self._eeprom:
                self.stats.bad("unsolicited_eeprom")
                return None
            return EepromWord(t, self._eeprom.popleft(), int.from_bytes(f[1:3], "big"))
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
