"""Keller PA-30X pressure transmitter: the Keller bus protocol (RS-485), sans-I/O.

Frames (docs/protocols.md, "Keller"): a request is ``addr, function, [data], CRC16``
and the answer repeats ``addr, function`` followed by its data and CRC16.  Used here:

* F48 initialise: request ``addr 0x30 crc``; answer ``addr 0x30 class group year week
  buffer state crc`` (10 bytes).
* F69 serial number: request ``addr 0x45 crc``; answer ``addr 0x45 n3 n2 n1 n0 crc``
  (8 bytes, a big-endian uint32; LSTS DUNE reads it after F48).
* F73 read a float channel: request ``addr 0x49 channel crc``; answer ``addr 0x49 b3 b2 b1
  b0 status crc`` (9 bytes, IEEE-754 big-endian).  Channel 1 is P1 in bar (absolute for
  the PA-30X), channel 4 is TOB1, the sensor temperature in degrees C.  Status bit 1
  flags a P1 measuring error and bit 4 a TOB1 error (*Communication protocol Serie 30*
  v2.2, section 4.8): such a reading is an error, not a value.
* An exception answer is ``addr (function | 0x80) code crc`` (5 bytes); code 32 means
  the device has not been initialised since power-up.

CRC16 is the Modbus polynomial (0xA001 reflected, initial 0xFFFF), sent high byte
first (the manual's example ``FA 30 04 43``; LSTS DUNE, Sensors/Keller, does the same).
"""

from __future__ import annotations

import struct
from collections import deque
from dataclasses import dataclass

from navd.drivers.codec import DeviceError, FrameDecoder
from navd.records import Pressure, implausible

F_INIT = 48
F_SERIAL = 69
F_READ_FLOAT = 73
CH_PRESSURE = 1
CH_TEMPERATURE = 4
# exception code 32: the device has not been initialised (after a power blip); F48 again
# (LSTS DUNE, Sensors/Keller)
E_NOT_INITIALISED = 32
# the status bit that flags each channel's reading as a measuring error
STATUS_ERROR = {CH_PRESSURE: 0x02, CH_TEMPERATURE: 0x10}
_LENGTHS = {F_INIT: 10, F_SERIAL: 8, F_READ_FLOAT: 9}
_LENGTHS.update({fn | 0x80: 5 for fn in tuple(_LENGTHS)})


def crc16(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def _with_crc(body: bytes) -> bytes:
    return body + crc16(body).to_bytes(2, "big")


def encode_init(addr: int) -> bytes:
    return _with_crc(bytes([addr, F_INIT]))


def encode_serial(addr: int) -> bytes:
    return _with_crc(bytes([addr, F_SERIAL]))


def encode_read_float(addr: int, channel: int) -> bytes:
    return _with_crc(bytes([addr, F_READ_FLOAT, channel]))


@dataclass(frozen=True, slots=True)
class DeviceInfo:
    t: float
    device_class: int
    group: int
    year: int
    week: int


@dataclass(frozen=True, slots=True)
class SerialNumber:
    t: float
    number: int


@dataclass(frozen=True, slots=True)
class Temperature:
    t: float
    c: float


class KellerDecoder(FrameDecoder):
    """Answers from one device address; channels of F73 answers are matched FIFO to requests."""

    def __init__(self, addr: int = 250, local_echo: bool = False) -> None:
        super().__init__()
        self.addr = addr
        self._pending: deque[int] = deque(maxlen=16)
        # An RS-485 adapter with local echo hands every request back before its answer
        # (LSTS DUNE, Sensors/Keller, "Serial Port - Local Echo"): expected, and dropped.
        self.local_echo = local_echo
        self._echoes: deque[bytes] = deque(maxlen=16)

    def _sent(self, frame: bytes) -> bytes:
        if self.local_echo:
            self._echoes.append(frame)
        return frame

    def request_init(self) -> bytes:
        return self._sent(encode_init(self.addr))

    def request_serial(self) -> bytes:
        return self._sent(encode_serial(self.addr))

    def request(self, channel: int) -> bytes:
        self._pending.append(channel)
        return self._sent(encode_read_float(self.addr, channel))

    def _frame_length(self, buf: bytearray) -> int | None:
        if self._echoes:
            echo = self._echoes[0]
            n = min(len(buf), len(echo))
            if buf[:n] == echo[:n]:
                return len(echo) if len(buf) >= len(echo) else 0
        if buf[0] != self.addr:
            return None
        if len(buf) < 2:
            return 0
        return _LENGTHS.get(buf[1])

    def _checksum_ok(self, frame: bytes) -> bool:
        return crc16(frame[:-2]).to_bytes(2, "big") == frame[-2:]

    def _parse(self, f: bytes, t: float) -> object | None:
        if self._echoes and f == self._echoes[0]:
            self._echoes.popleft()
            self.stats.reasons["echo"] = self.stats.reasons.get("echo", 0) + 1
            return None
        fn = f[1]
        if fn & 0x80:
            if fn & 0x7F == F_READ_FLOAT and self._pending:
                self._pending.popleft()  # that request is answered: the next is another's
            code = f[2]
            # not initialised (a power blip): F48 again, as DUNE's Keller task does
            send = self.request_init() if code == E_NOT_INITIALISED else b""
            return DeviceError(t, code, f"F{fn & 0x7F} exception {code}", send)
        if fn == F_INIT:
            return DeviceInfo(t, f[2], f[3], f[4], f[5])
        if fn == F_SERIAL:
            return SerialNumber(t, int.from_bytes(f[2:6], "big"))
        (value,) = struct.unpack(">f", f[2:6])
        channel = self._pending.popleft() if self._pending else CH_PRESSURE
        status = f[6]
        if status & STATUS_ERROR.get(channel, 0):
            name = "P1" if channel == CH_PRESSURE else "TOB1"
            return DeviceError(t, status, f"{name} measuring error (status 0x{status:02X})")
        if channel == CH_TEMPERATURE:
            if not -60.0 <= value <= 150.0:  # NaN fails too: the sensor says nonsense
                self.stats.bad("bad_value")
                return None
            return Temperature(t, value)
        rec = Pressure(t, value)
        if implausible(rec) is not None:  # the log reader's bounds: live and replay agree
            self.stats.bad("bad_value")
            return None
        return rec
