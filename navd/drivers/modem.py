"""Teledyne Benthos ATM-903 acoustic modem in AT command mode, sans-I/O.

navd asks the modem for the range to the UDB-9400 deck box with ``ATRX<addr>``
("range and location", seed 000 section 4.1); the deck box answers with its
position (latitude, longitude, depth) which the modem prints after the range.
Replies are CR LF terminated text lines (docs/protocols.md, "Benthos"):

    TX time ...
    Range 1 to 2 : 153.4 m  (Round-trip  204.5 ms) speed  0.0 m/s
    Remote Lat: 37.0490112 Lon: -80.6670001 Depth: 3.0
    OK

The ``Range`` line alone is the ranging result (the Goby3 ATM-900 driver reads it
so).  Its location line, when the deck box sends one, follows at once: the range is
held for it at most ``LOCATION_WAIT_S`` after its own line, and whatever comes first
-- the location, any other line, or ``expire(t)`` past the wait -- completes it.  It
keeps the time its own line arrived.

A ping that gets no answer ends with ``Response Not Received.`` after the modem's own
timeout (or ``Timeout``).  The modem refuses a command with ``ERROR``, and its shell
refuses one it does not know with ``Command '...' not found``: both are refusals.
Parsing is by pattern and tolerant of spacing, case and of the location line being
absent or garbled (then the range is kept and its location left empty).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from enum import StrEnum

from navd.drivers.codec import DecodeStats

_RANGE = re.compile(rb"range\s*(?:\d+\s*to\s*(\d+))?\s*[:=]\s*([0-9]+(?:\.[0-9]*)?)\s*m", re.I)
_ROUND_TRIP = re.compile(rb"round-?trip\s*[:=]?\s*([0-9]+(?:\.[0-9]*)?)\s*ms", re.I)
_SPEED = re.compile(rb"speed\s*[:=]?\s*([-+]?[0-9]+(?:\.[0-9]*)?)\s*m/s", re.I)
_LOC = re.compile(
    rb"lat\w*\s*[:=]\s*(-?[0-9.]+)\s*,?\s*lon\w*\s*[:=]\s*(-?[0-9.]+)"
    rb"(?:\s*,?\s*depth\s*[:=]\s*(-?[0-9.]+))?",
    re.I,
)
_NO_REPLY = re.compile(rb"response not received|timeout|timed out", re.I)
_REFUSED = re.compile(rb"^error\b|^command\s+'.*'\s+not\s+found", re.I)
_ESCAPE_ANSWER = re.compile(rb"^command\s+'\+\+\+'\s+not\s+found", re.I)
_PROMPT = re.compile(rb"^user:\s*\d*\s*(\w*)\s*>", re.I)
_CONNECT = re.compile(rb"^connect", re.I)
# lines the modem prints that carry nothing for ranging: the transmit report before a
# range, received data packets, the echo of a command
_IGNORED = re.compile(rb"^(tx time|data\(|source\s*:|crc\s*:|<eop>|at|>)", re.I)
_MAX_LINE = 200
# the location line follows its range line at once (about 55 bytes: 60 ms at 9600 baud)
LOCATION_WAIT_S = 0.5


def encode_range(remote: int) -> bytes:
    return f"ATRX{remote}\r".encode("ascii")


@dataclass(frozen=True, slots=True)
class ModemRange:
    t: float
    range_m: float
    remote: int | None
    lat: float | None = None
    lon: float | None = None
    depth: float | None = None
    twtt_s: float | None = None  # the round trip the modem measured
    speed_mps: float | None = None  # its relative speed to the remote


class Mode(StrEnum):
    """What the modem said of its mode (strings, as health publishes them)."""

    UNKNOWN = "unknown"
    COMMAND = "command"
    ONLINE = "online"
    LOWPOWER = "lowpower"


class Reply(StrEnum):
    """How a command ended."""

    OK = "ok"
    REFUSED = "refused"
    NO_REPLY = "no_reply"


@dataclass(frozen=True, slots=True)
class ModemMode:
    """What the modem said of its mode: ``command`` (its shell prompt, or ``+++``
    refused because it is already there), ``online`` (``CONNECT``: data mode, where
    commands are data) or ``lowpower`` (a ``Lowpower`` prompt)."""

    t: float
    mode: Mode


@dataclass(frozen=True, slots=True)
class ModemReply:
    """The end of a command: ``ok``, ``refused`` (``ERROR`` or ``Command '...' not found``)
    or ``no_reply`` (the remote never answered)."""

    t: float
    status: Reply


def _num(b: bytes | None, lo: float, hi: float) -> float | None:
    if b is None:
        return None
    try:
        v = float(b)
    except ValueError:
        return None
    return v if math.isfinite(v) and lo <= v <= hi else None


class ModemDecoder:
    def __init__(self) -> None:
        self.stats = DecodeStats()
        self._buf = bytearray()
        self._range: ModemRange | None = None

    def reset(self) -> None:
        self._buf.clear()
        self._range = None

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        self._buf += data
        out: list[object] = []
        while True:
            i = min(
                (p for p in (self._buf.find(b"\r"), self._buf.find(b"\n")) if p >= 0), default=-1
            )
            if i < 0:
                if _PROMPT.match(bytes(self._buf).strip()) and self._buf.rstrip().endswith(b">"):
                    # the shell's prompt waits for input on its own line: no CR LF after it
                    line = bytes(self._buf).strip()
                    self._buf.clear()
                    out.extend(self._line(line, t))
                    break
                if len(self._buf) > _MAX_LINE:
                    self.stats.skip(len(self._buf), "too_long")
                    self.stats.bad_frame += 1
                    self._buf.clear()
                break
            line = bytes(self._buf[:i]).strip()
            del self._buf[: i + 1]
            if line:
                out.extend(self._line(line, t))
        return out

    def expire(self, t: float) -> list[object]:
        """The held range, once its location line has had ``LOCATION_WAIT_S`` to come."""
        if self._range is not None and t - self._range.t >= LOCATION_WAIT_S:
            return self._flush()
        return []

    def _flush(self) -> list[object]:
        if self._range is None:
            return []
        r, self._range = self._range, None
        self.stats.records += 1
        return [r]

    def _line(self, line: bytes, t: float) -> list[object]:
        m = _RANGE.search(line)
        if m:
            out = self._flush()
            rng = _num(m.group(2), 0.0, 1e5)
            if rng is None:
                self.stats.bad_frame += 1
                self.stats.skip(len(line), "bad_range")
                return out
            remote = int(m.group(1)) if m.group(1) else None
            rt, sp = _ROUND_TRIP.search(line), _SPEED.search(line)
            rtt_ms = _num(rt.group(1), 0.0, 1e6) if rt else None
            self._range = ModemRange(
                t,
                rng,
                remote,
                twtt_s=None if rtt_ms is None else rtt_ms / 1000.0,
                speed_mps=_num(sp.group(1), -100.0, 100.0) if sp else None,
            )
            return out
        m = _LOC.search(line)
        if m:
            if self._range is None:
                self.stats.skip(len(line), "location_without_range")
                return []
            self._range = replace(
                self._range,
                lat=_num(m.group(1), -90.0, 90.0),
                lon=_num(m.group(2), -180.0, 180.0),
                depth=_num(m.group(3), -100.0, 11000.0),
            )
            return self._flush()
        if line.upper() == b"OK":
            return [*self._flush(), ModemReply(t, Reply.OK)]
        if _ESCAPE_ANSWER.search(line):
            return [*self._flush(), ModemMode(t, Mode.COMMAND)]
        m = _PROMPT.search(line)
        if m:
            low = m.group(1).lower().startswith(b"lowpower")
            return [*self._flush(), ModemMode(t, Mode.LOWPOWER if low else Mode.COMMAND)]
        if _CONNECT.search(line):
            return [*self._flush(), ModemMode(t, Mode.ONLINE)]
        if _REFUSED.search(line):
            return [*self._flush(), ModemReply(t, Reply.REFUSED)]
        if _NO_REPLY.search(line):
            return [*self._flush(), ModemReply(t, Reply.NO_REPLY)]
        out = self._flush()
        if not _IGNORED.search(line):
            self.stats.skip(len(line), "unrecognised")
        return out


#: silence on the line before ``+++`` (the modem wants 1 s; Goby's driver waits 1.3 s)
GUARD_S = 1.3
#: an escape or an ``AT`` unanswered this long is tried again
ANSWER_S = 3.0


class _Step(StrEnum):
    """Where the session is in getting the modem to its shell."""

    ESCAPE = "escape"  # to send ``+++`` once the line has been quiet for GUARD_S
    ESCAPING = "escaping"  # sent; waiting for the prompt
    CHECK = "check"  # to send ``AT``
    CHECKING = "checking"  # sent; waiting for ``OK``
    READY = "ready"  # in command mode: pings may go


class ModemSession:
    """Keeps the modem in command mode, sans-I/O: told what the modem said, asked what
    to send.

    After power-up or a ``CONNECT`` the ATM-900 is online, and everything sent to it
    is data for the acoustic link: ``ATRX`` would never be answered.  So after every
    open of the port, every ``CONNECT`` or ``Lowpower`` prompt, and every ping the
    modem never answered at all, the session escapes (``+++`` after ``GUARD_S`` of
    silence) and checks the shell with ``AT`` -> ``OK``.  Pings go only while
    ``ready``.
    """

    def __init__(self) -> None:
        self.mode = Mode.UNKNOWN  # what the modem last said
        self.escapes = 0
        self._step = _Step.ESCAPE
        self._t_tx = -math.inf  # our last write: the guard is silence after it
        self._t_step = -math.inf
        self.t_unready: float | None = None  # since when pings cannot go (None: ready)

    @property
    def ready(self) -> bool:
        return self._step is _Step.READY

    def opened(self, t: float) -> None:
        self.mode = Mode.UNKNOWN
        self._escape(t)
        self._t_tx = t

    def wrote(self, t: float) -> None:
        self._t_tx = t

    def lost(self, t: float) -> None:
        """A command the modem never answered, not even with ``Response Not Received.``."""
        self.mode = Mode.UNKNOWN
        self._escape(t)

    def seen(self, rec: ModemMode | ModemReply) -> None:
        if isinstance(rec, ModemMode):
            self.mode = rec.mode
            if rec.mode != Mode.COMMAND:
                self._escape(rec.t)
            elif self._step in (_Step.ESCAPE, _Step.ESCAPING):
                self._step = _Step.CHECK
        elif rec.status == Reply.OK and self._step is _Step.CHECKING:
            self.mode = Mode.COMMAND
            self._step = _Step.READY
            self.t_unready = None

    def _escape(self, t: float) -> None:
        if self._step is _Step.READY or self.t_unready is None:
            self.t_unready = t
        self._step = _Step.ESCAPE

    def poll(self, t: float) -> bytes:
        """What to send now (often nothing)."""
        if self._step is _Step.ESCAPE and t - self._t_tx >= GUARD_S:
            self._step, self._t_step = _Step.ESCAPING, t
            self.escapes += 1
            return self._sent(t, b"+++\r")
        if self._step is _Step.ESCAPING and t - self._t_step >= ANSWER_S:
            self._step = _Step.CHECK  # no prompt came: it may be in command mode already
        if self._step is _Step.CHECK:
            self._step, self._t_step = _Step.CHECKING, t
            return self._sent(t, b"AT\r")
        if self._step is _Step.CHECKING and t - self._t_step >= ANSWER_S:
            self._step = _Step.ESCAPE  # AT unanswered: online, or asleep
        return b""

    def _sent(self, t: float, data: bytes) -> bytes:
        self._t_tx = t
        return data
