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

from navd.formats import jsonlines
from navd.records import (
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
#: a longer step forward between two records is checked against the record after it
JUMP_S = 60.0
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
    if fix == 0:
        return Gps(t, None, None, None, 0, hdop, quality)
    return Gps(t, _num(o, "lat"), _num(o, "lon"), _opt(o, "alt"), fix, hdop, quality)


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


def iter_lines(
    lines: Iterable[str], strict: bool = False
) -> Iterator[tuple[int, Record | Skipped]]:
    """Records (or skips) from the lines after the header, numbered from 2.

    Time must not go back, except for a range completed up to ``MAX_LATE_S`` after
    the records behind its first byte (the daemon logs it when complete).  A record
    more than ``JUMP_S`` ahead of the one before is held until the next one shows
    whether time really moved on (a gap in the log) or that record is corrupt; a
    corrupt one is skipped, not made the new clock that every later line would
    then go back from.
    """
    last_t = -math.inf
    held: tuple[int, Record] | None = None
    for no, raw in enumerate(lines, start=2):
        if len(raw) > MAX_LINE_CHARS:
            reason = f"line longer than {MAX_LINE_CHARS} characters"
            if strict:
                raise LogError(f"line {no}: {reason}")
            yield no, Skipped(no, reason)
            continue
        line = raw.strip()
        if not line:
            continue
        try:
            try:
                obj = jsonlines.loads(line)
            except jsonlines.DecodeError as exc:
                raise ValueError(f"invalid JSON ({exc.__class__.__name__})") from None
            if isinstance(obj, dict) and obj.get("type") == "estimate":
                t_tick = obj.get("t")
                if isinstance(t_tick, float | int) and math.isfinite(t_tick):
                    yield no, Tick(float(t_tick))  # where the daemon stepped its filter
                continue
            if isinstance(obj, dict) and obj.get("type") in LOG_ONLY_TYPES:
                continue
            rec = parse_record(obj)
            if held is not None:
                h_no, h_rec = held
                held = None
                if rec.t >= h_rec.t - MAX_LATE_S:
                    last_t = h_rec.t
                    yield h_no, h_rec
                else:
                    why = f"t={h_rec.t:g} is far out of line (before {last_t:g}, after {rec.t:g})"
                    if strict:
                        raise LogError(f"line {h_no}: {why}")
                    yield h_no, Skipped(h_no, why)
            late_ok = MAX_LATE_S if isinstance(rec, Range | TravelTime) else 0.0
            if rec.t < last_t - late_ok:
                raise ValueError(f"t={rec.t:g} goes back in time (previous {last_t:g})")
        except ValueError as exc:
            if strict:
                raise LogError(f"line {no}: {exc}") from None
            yield no, Skipped(no, str(exc))
            continue
        if math.isfinite(last_t) and rec.t - last_t > JUMP_S:
            held = (no, rec)
            continue
        last_t = max(last_t, rec.t)
        yield no, rec
    if held is not None:
        yield held


def _bounded_lines(fh: IO[str]) -> Iterator[str]:
    """The file's lines, none held longer than ``MAX_LINE_CHARS + 1`` characters.

    A longer line is cut there (so the reader skips it) and the rest of it is read
    past in bounded pieces: one corrupt line must not cost the memory of its length.
    """
    while True:
        line = fh.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        if len(line) > MAX_LINE_CHARS and not line.endswith("\n"):
            while True:
                rest = fh.readline(MAX_LINE_CHARS)
                if not rest or rest.endswith("\n"):
                    break
        yield line


def read_measurement_log(path: str | Path, strict: bool = False) -> MeasurementLog:
    p = Path(path)
    try:
        fh = p.open("r", encoding="utf-8", errors="strict")
    except OSError as exc:
        raise LogError(f"{p}: cannot open ({exc.strerror or exc})") from None
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
    except UnicodeDecodeError as exc:
        raise LogError(f"{p}: not UTF-8 text ({exc.reason})") from None
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
