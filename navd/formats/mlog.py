"""Measurement log, version 1: reader and writer (``shared/spec/replay-interface.md``).

JSON Lines; a header line, then one record per line.  The reader never raises on
bad content: each malformed line is skipped and reported as a :class:`Skipped`
with its line number and reason, unless ``strict`` asks for the first one to be
fatal (:class:`LogError`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import IO, Any

from navd import files
from navd.formats import jsonlines
from navd.records import (
    MAX_ABS_T,
    MAX_LATE_S,
    TYPE_NAMES,
    Attitude,
    Depth,
    Gps,
    Heading,
    Pressure,
    Range,
    Record,
    Reset,
    Rpm,
    SetBeacon,
    Tick,
    TravelTime,
    Velocity,
    implausible,
)

FORMAT = "navd-measurements"
#: what the daemon's own log holds besides measurements; replay passes over them
LOG_ONLY_TYPES = frozenset({"raw", "estimate", "decision", "health", "advisory", "event"})
VERSION = 1
#: a longer step forward is held until the lines after it confirm it (``_TimeRules``):
#: records come at 10 Hz and more, so a few seconds of silence is already a gap
JUMP_S = 5.0
#: records after a jump that, following it, make it the new clock
CONFIRM_LINES = 8
#: no record is anywhere near this long; a longer line is skipped without parsing it
MAX_LINE_CHARS = 65536

__all__ = ["LogError", "Skipped", "MeasurementLog", "read_measurement_log", "MeasurementWriter"]


class LogError(Exception):
    """A log that cannot be read at all, or the first bad line under ``strict``; one line."""


@dataclass(frozen=True, slots=True)
class Skipped:
    line: int
    reason: str


@dataclass(slots=True)
class MeasurementLog:
    header: dict[str, Any]
    records: list[Record]
    skipped: list[Skipped]


class _Bad(Exception):
    pass


def _num(obj: dict, key: str) -> float:
    """A number field; its bounds are checked on the whole record (records.implausible)."""
    if key not in obj:
        raise _Bad(f"missing field '{key}'")
    v = obj[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise _Bad(f"field '{key}' must be a number, got {type(v).__name__}")
    if not math.isfinite(v):
        raise _Bad(f"field '{key}' is not finite")
    return float(v)


def _opt(obj: dict, key: str) -> float | None:
    if obj.get(key) is None:
        return None
    return _num(obj, key)


def _str(obj: dict, key: str) -> str:
    v = obj.get(key)
    if not isinstance(v, str) or not v:
        raise _Bad(f"field '{key}' must be a non-empty string")
    return v


def _beacon_fields(obj: dict) -> tuple[float | None, float | None, float | None]:
    return _opt(obj, "beacon_lat"), _opt(obj, "beacon_lon"), _opt(obj, "beacon_depth")


def _parse_gps(o: dict, t: float) -> Gps:
    fix = o.get("fix")
    if isinstance(fix, bool) or not isinstance(fix, int) or fix not in (0, 1, 2):
        raise _Bad("field 'fix' must be 0, 1 or 2")
    hdop = _opt(o, "hdop")
    quality = o.get("quality")
    if quality is not None and (
        isinstance(quality, bool) or not isinstance(quality, int) or not 0 <= quality <= 9
    ):
        raise _Bad("field 'quality' must be an integer 0 to 9")
    sats = o.get("sats")
    if sats is not None and (isinstance(sats, bool) or not isinstance(sats, int)):
        raise _Bad("field 'sats' must be an integer")
    if fix == 0:
        return Gps(t, None, None, None, 0, hdop, quality, sats=sats)
    return Gps(
        t, _num(o, "lat"), _num(o, "lon"), _opt(o, "alt"), fix, hdop, quality,
        _opt(o, "alt_msl"), _opt(o, "geoid_sep"), sats,
    )


def _parse_range(o: dict, t: float) -> Range:
    return Range(
        t,
        _num(o, "t_ping"),
        _num(o, "m"),
        _str(o, "beacon"),
        *_beacon_fields(o),
        _opt(o, "twtt_s"),
        _opt(o, "speed_mps"),
    )


def _parse_tt(o: dict, t: float) -> TravelTime:
    return TravelTime(
        t, _num(o, "t_ping"), _num(o, "twtt_s"), _str(o, "beacon"), *_beacon_fields(o)
    )


_PARSERS: dict[str, Callable[[dict, float], Record]] = {
    "heading": lambda o, t: Heading(t, _num(o, "deg")),
    "attitude": lambda o, t: Attitude(
        t, _num(o, "roll_deg"), _num(o, "pitch_deg"), _num(o, "yaw_deg")
    ),
    "rpm": lambda o, t: Rpm(t, _num(o, "rpm")),
    "depth": lambda o, t: Depth(t, _num(o, "m")),
    "pressure": lambda o, t: Pressure(t, _num(o, "bar")),
    "gps": _parse_gps,
    "range": _parse_range,
    "travel_time": _parse_tt,
    "velocity": lambda o, t: Velocity(t, _num(o, "u"), _num(o, "v"), _num(o, "w")),
    "cmd_reset": lambda o, t: Reset(t),
    "cmd_beacon": lambda o, t: SetBeacon(
        t,
        _str(o, "beacon"),
        _num(o, "lat"),
        _num(o, "lon"),
        _opt(o, "depth") or 0.0,
    ),
}


def parse_record(obj: Any) -> Record:
    """One decoded JSON object to a record; raises ``ValueError`` with the reason."""
    try:
        if not isinstance(obj, dict):
            raise _Bad("not a JSON object")
        kind = obj.get("type")
        parser = _PARSERS.get(kind) if isinstance(kind, str) else None
        if parser is None:
            raise _Bad(f"unknown record type {kind!r}")
        rec = parser(obj, _num(obj, "t"))
        why = implausible(rec)
        if why is not None:
            raise _Bad(why)
        return rec
    except _Bad as exc:
        raise ValueError(str(exc)) from None


def _check_header(obj: Any) -> dict[str, Any]:
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise LogError(f"line 1: not a measurement log header (expected format '{FORMAT}')")
    if obj.get("version") != VERSION:
        raise LogError(
            f"line 1: unsupported version {obj.get('version')!r} (reader knows {VERSION})"
        )
    return obj


class _TimeRules:
    """Replay's time rules, one place for every line alike (measurements and ticks).

    Time must not go back, except for a range completed up to ``MAX_LATE_S`` after
    the records behind its first byte (the daemon logs it when complete).  A record
    more than ``JUMP_S`` ahead of the clock is held, with the records after it, until
    ``CONFIRM_LINES`` of them follow it (time really moved on: a gap in the log) or
    one does not (they are out of line, dropped and counted; the clock stays).  The
    end of the log confirms what is held.  So one corrupt time, or a few in a row,
    costs its own lines and never becomes the clock every later line goes back from.
    """

    def __init__(self, strict: bool) -> None:
        self.strict = strict
        self.last_t = -math.inf
        self.held: list[tuple[int, Record]] = []
        self.held_max = -math.inf

    def _skip(self, no: int, why: str) -> tuple[int, Skipped]:
        if self.strict:
            raise LogError(f"line {no}: {why}")
        return no, Skipped(no, why)

    def offer(self, no: int, rec: Record) -> list[tuple[int, Record | Skipped]]:
        late_ok = MAX_LATE_S if isinstance(rec, Range | TravelTime) else 0.0
        out: list[tuple[int, Record | Skipped]] = []
        if self.held:
            if rec.t >= self.held_max - late_ok:
                self.held.append((no, rec))
                self.held_max = max(self.held_max, rec.t)
                if len(self.held) > CONFIRM_LINES:
                    out += self._release()
                return out
            for h_no, h_rec in self.held:
                out.append(
                    self._skip(
                        h_no,
                        f"t={h_rec.t:g} is far out of line (after {self.last_t:g}, "
                        f"and line {no} goes on from t={rec.t:g})",
                    )
                )
            self.held, self.held_max = [], -math.inf
        if rec.t < self.last_t - late_ok:
            out.append(self._skip(no, f"t={rec.t:g} goes back in time (previous {self.last_t:g})"))
        elif math.isfinite(self.last_t) and rec.t - self.last_t > JUMP_S:
            self.held, self.held_max = [(no, rec)], rec.t
        else:
            self.last_t = max(self.last_t, rec.t)
            out.append((no, rec))
        return out

    def _release(self) -> list[tuple[int, Record | Skipped]]:
        out: list[tuple[int, Record | Skipped]] = list(self.held)
        self.last_t = self.held_max
        self.held, self.held_max = [], -math.inf
        return out

    def finish(self) -> list[tuple[int, Record | Skipped]]:
        return self._release() if self.held else []


def iter_lines(
    lines: Iterable[str | bytes], strict: bool = False
) -> Iterator[tuple[int, Record | Skipped]]:
    """Records (or skips) from the lines after the header, numbered from 2.

    Each line is decoded on its own (invalid UTF-8 costs that line) and put through
    :class:`_TimeRules`; an ``estimate`` line of a daemon log is a :class:`Tick`.
    """
    rules = _TimeRules(strict)
    for no, raw in enumerate(lines, start=2):
        if len(raw) > MAX_LINE_CHARS:
            reason = f"line longer than {MAX_LINE_CHARS} characters"
            if strict:
                raise LogError(f"line {no}: {reason}")
            yield no, Skipped(no, reason)
            continue
        try:
            if isinstance(raw, bytes):
                try:
                    raw = raw.decode("utf-8")
                except UnicodeDecodeError:
                    raise ValueError("invalid UTF-8") from None
            line = raw.strip()
            if not line:
                continue
            try:
                obj = jsonlines.loads(line)
            except jsonlines.DecodeError as exc:
                raise ValueError(f"invalid JSON ({exc.__class__.__name__})") from None
            rec: Record
            if isinstance(obj, dict) and obj.get("type") == "estimate":
                t_tick = obj.get("t")
                if isinstance(t_tick, bool) or not isinstance(t_tick, float | int):
                    continue
                if not (math.isfinite(t_tick) and abs(t_tick) <= MAX_ABS_T):
                    raise ValueError(f"estimate line with an impossible time {t_tick!r:.20}")
                rec = Tick(float(t_tick))  # where the daemon stepped its filter
            elif isinstance(obj, dict) and obj.get("type") in LOG_ONLY_TYPES:
                continue
            else:
                rec = parse_record(obj)
        except ValueError as exc:
            if strict:
                raise LogError(f"line {no}: {exc}") from None
            yield no, Skipped(no, str(exc))
            continue
        yield from rules.offer(no, rec)
    yield from rules.finish()


def _bounded_lines(fh: IO[bytes]) -> Iterator[bytes]:
    """The file's lines, none held longer than ``MAX_LINE_CHARS + 1`` bytes.

    A longer line is cut there (so the reader skips it) and the rest of it is read
    past in bounded pieces: one corrupt line must not cost the memory of its length.
    """
    while True:
        line = fh.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        if len(line) > MAX_LINE_CHARS and not line.endswith(b"\n"):
            while True:
                rest = fh.readline(MAX_LINE_CHARS)
                if not rest or rest.endswith(b"\n"):
                    break
        yield line


def read_measurement_log(path: str | Path, strict: bool = False) -> MeasurementLog:
    p = Path(path)
    try:
        fh = files.open_regular(p)
    except files.FileRefused as exc:
        raise LogError(str(exc)) from None
    try:
        with fh:
            first = fh.readline(MAX_LINE_CHARS)
            if not first:
                raise LogError(f"{p}: empty file, expected a measurement log header")
            try:
                header = _check_header(jsonlines.loads(first))
            except jsonlines.DecodeError:
                raise LogError(f"{p}: line 1: header is not valid JSON") from None
            records: list[Record] = []
            skipped: list[Skipped] = []
            for _, item in iter_lines(_bounded_lines(fh), strict):
                if isinstance(item, Skipped):
                    skipped.append(item)
                else:
                    records.append(item)
    except OSError as exc:
        raise LogError(f"{p}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
    except LogError as exc:
        msg = str(exc)
        raise LogError(msg if msg.startswith(str(p)) else f"{p}: {msg}") from None
    return MeasurementLog(header, records, skipped)


def record_to_json(rec: Record) -> dict[str, Any]:
    out: dict[str, Any] = {"type": TYPE_NAMES[type(rec)]}
    for f in fields(rec):
        v = getattr(rec, f.name)
        if v is None:
            continue
        out[f.name] = v
    return out


class MeasurementWriter:
    """Writes a measurement log v1 to an open text stream."""

    def __init__(self, fh: IO[str], start_utc: str, **extra: Any) -> None:
        self._fh = fh
        header = {"format": FORMAT, "version": VERSION, "start_utc": start_utc, **extra}
        fh.write(jsonlines.dumps_line(header))

    def write(self, rec: Record) -> None:
        self._fh.write(jsonlines.dumps_line(record_to_json(rec)))
