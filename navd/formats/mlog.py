"""Measurement log, version 1: reader and writer (``shared/spec/replay-interface.md``).

JSON Lines; a header line, then one record per line.  The reader never raises on
bad content: each malformed line is skipped and reported as a :class:`Skipped`
with its line number and reason, unless ``strict`` asks for the first one to be
fatal (:class:`LogError`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, fields
from pathlib import Path
from typing import IO

from navd import files
from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.records import (
    BEACON_NAME,
    MAX_ABS_T,
    MAX_LATE_S,
    TYPE_NAMES,
    Attitude,
    Clock,
    Depth,
    Gps,
    Heading,
    Pressure,
    Range,
    Record,
    Reset,
    Resume,
    Rpm,
    SetBeacon,
    Tick,
    TravelTime,
    Velocity,
    implausible,
)
from navd.utc import utc_seconds

FORMAT = "navd-measurements"
#: what the daemon's own log holds besides measurements; replay passes over them
LOG_ONLY_TYPES = frozenset({"raw", "estimate", "decision", "health", "advisory", "event"})
VERSION = 1
#: lines each record waits for before replay takes it (``_TimeRules``): the lines that
#: outvote a corrupt time
HOLD_LINES = 16
#: no record is anywhere near this long; a longer line is skipped without parsing it
MAX_LINE_CHARS = 65536

__all__ = [
    "LogError",
    "Skipped",
    "MeasurementLog",
    "read_measurement_log",
    "MeasurementWriter",
    "log_epoch",
]


class LogError(Exception):
    """A log that cannot be read at all, or the first bad line under ``strict``; one line."""


@dataclass(frozen=True, slots=True)
class Skipped:
    line: int
    reason: str


@dataclass(slots=True)
class MeasurementLog:
    header: JsonObject
    records: list[Record]
    skipped: list[Skipped]


class _Bad(Exception):
    pass


def _num(obj: JsonObject, key: str) -> float:
    """A number field; its bounds are checked on the whole record (records.implausible)."""
    v = obj.get(key)
    if type(v) is float and v - v == 0.0:  # finite: nearly every field of every line
        return v
    if key not in obj:
        raise _Bad(f"missing field '{key}'")
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise _Bad(f"field '{key}' must be a number, got {type(v).__name__}")
    if not math.isfinite(v):
        raise _Bad(f"field '{key}' is not finite")
    return float(v)


def _opt(obj: JsonObject, key: str) -> float | None:
    if obj.get(key) is None:
        return None
    return _num(obj, key)


def _str(obj: JsonObject, key: str) -> str:
    v = obj.get(key)
    if not isinstance(v, str) or not v:
        raise _Bad(f"field '{key}' must be a non-empty string")
    return v


def _beacon_name(obj: JsonObject) -> str:
    name = _str(obj, "beacon")
    if not BEACON_NAME.fullmatch(name):
        raise _Bad("field 'beacon': 1 to 32 letters, digits, '_', '.' or '-' (as the command)")
    return name


def _beacon_fields(obj: JsonObject) -> tuple[float | None, float | None, float | None]:
    return _opt(obj, "beacon_lat"), _opt(obj, "beacon_lon"), _opt(obj, "beacon_depth")


def _parse_gps(o: JsonObject, t: float) -> Gps:
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


def _numbers(obj: JsonObject, key: str, max_len: int = 256) -> tuple[float, ...]:
    v = obj.get(key)
    if not isinstance(v, list) or not v or len(v) > max_len:
        raise _Bad(f"field '{key}' must be a list of at most {max_len} numbers")
    out = []
    for a in v:
        if isinstance(a, bool) or not isinstance(a, int | float) or not math.isfinite(a):
            raise _Bad(f"field '{key}' must hold finite numbers")
        out.append(float(a))
    return tuple(out)


def _exactly(o: JsonObject, key: str, n: int) -> tuple[float, ...] | None:
    """An optional field of exactly ``n`` numbers (None: absent)."""
    if o.get(key) is None:
        return None
    v = _numbers(o, key, n)
    if len(v) != n:
        raise _Bad(f"field '{key}' must hold {n} numbers")
    return v


def _parse_resume(o: JsonObject, t: float) -> Resume:
    mode = o.get("mode")
    if mode not in ("default", "thesis", "vlbl"):
        raise _Bad("field 'mode' must be default, thesis or vlbl")
    x = _numbers(o, "x", 16)
    P = _numbers(o, "P", 256)
    if len(P) != len(x) ** 2:
        raise _Bad("field 'P' must hold len(x) squared numbers")
    outage = _exactly(o, "beacon_outage", 8)
    counts = _exactly(o, "long_refused", 2)
    long_refused = None if counts is None else (counts[0], counts[1])
    range_noise = _exactly(o, "range_noise", 4)
    return Resume(
        t, mode, x, P, _num(o, "age_s"), _opt(o, "surface_bar"), _opt(o, "surface_alt"),
        _opt(o, "depth_m"), _opt(o, "range_scale"), _opt(o, "range_scale_var"), outage,
        long_refused, range_noise,
    )


def _parse_range(o: JsonObject, t: float) -> Range:
    return Range(
        t,
        _num(o, "t_ping"),
        _num(o, "m"),
        _str(o, "beacon"),
        *_beacon_fields(o),
        _opt(o, "twtt_s"),
        _opt(o, "speed_mps"),
    )


def _parse_tt(o: JsonObject, t: float) -> TravelTime:
    return TravelTime(
        t, _num(o, "t_ping"), _num(o, "twtt_s"), _str(o, "beacon"), *_beacon_fields(o)
    )


_PARSERS: dict[str, Callable[[JsonObject, float], Record]] = {
    "heading": lambda o, t: Heading(t, _num(o, "deg")),
    "attitude": lambda o, t: Attitude(
        t, _num(o, "roll_deg"), _num(o, "pitch_deg"), _num(o, "yaw_deg")
    ),
    "rpm": lambda o, t: Rpm(t, _num(o, "rpm")),
    "depth": lambda o, t: Depth(t, _num(o, "m")),
    "pressure": lambda o, t: Pressure(t, _num(o, "bar")),
    "gps": _parse_gps,
    "cmd_resume": _parse_resume,
    "range": _parse_range,
    "travel_time": _parse_tt,
    "velocity": lambda o, t: Velocity(t, _num(o, "u"), _num(o, "v"), _num(o, "w")),
    "cmd_reset": lambda o, t: Reset(t),
    "clock": lambda o, t: Clock(t, _num(o, "utc_s")),
    "cmd_beacon": lambda o, t: SetBeacon(
        t,
        _beacon_name(o),
        _num(o, "lat"),
        _num(o, "lon"),
        _opt(o, "depth") or 0.0,
    ),
}


def parse_record(obj: object) -> Record:
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


def log_epoch(header: JsonObject) -> float | None:
    """UTC seconds (since the Unix epoch) at the log's t = 0: its start, less the
    monotonic clock then where the daemon stamped its records with that clock; None where
    the header does not say."""
    t0 = utc_seconds(header.get("start_utc"))
    if t0 is None:
        return None
    if header.get("time_base") == "monotonic":
        mono = header.get("start_monotonic")
        if not isinstance(mono, int | float) or isinstance(mono, bool):
            return None
        t0 -= float(mono)
    return t0 if math.isfinite(t0) else None


def _check_header(obj: object) -> JsonObject:
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise LogError(f"line 1: not a measurement log header (expected format '{FORMAT}')")
    if obj.get("version") != VERSION:
        raise LogError(
            f"line 1: unsupported version {obj.get('version')!r} (reader knows {VERSION})"
        )
    return obj


# How far a record may lie behind the records logged before it.  A range is logged when
# its reply completes; a tick when the loop gets to it, after the records that arrived
# since its deadline, and one behind the clock steps nothing, so any lateness is harmless.
_LATE_OK: dict[type, float] = {Range: MAX_LATE_S, TravelTime: MAX_LATE_S, Tick: math.inf}


def _late_ok(rec: Record) -> float:
    """How far ``rec`` may lie behind the records logged before it (``_LATE_OK``)."""
    return _LATE_OK.get(type(rec), 0.0)


class _TimeRules:
    """Replay's time rules, one place for every line alike (measurements and ticks).

    Time must not go back, except for a range completed up to ``MAX_LATE_S`` after
    the records behind its first byte (the daemon logs it when complete).  Every
    record waits in a window of ``HOLD_LINES`` lines before it is given on.  While
    the window's times are in order that is all.  When they are not, a record leaves
    the window only if it belongs to the longest run of the window's records whose
    times are in order (and after what was given on): a corrupt time, ahead or
    behind, or a few of them in a row, is outvoted by the lines around it, dropped
    and counted, and never becomes the clock every later line would go back from.
    A real gap in the log is in order, and costs nothing.
    """

    def __init__(self, strict: bool) -> None:
        self.strict = strict
        self.window: deque[tuple[int, Record]] = deque()
        self.last_t = -math.inf  # the time of what was given on
        self.run_max = -math.inf  # the latest time in the window, while it is in order
        self.conflicted = False

    def _skip(self, no: int, why: str) -> tuple[int, Skipped]:
        if self.strict:
            raise LogError(f"line {no}: {why}")
        return no, Skipped(no, why)

    def offer(self, no: int, rec: Record) -> list[tuple[int, Record | Skipped]]:
        late = _late_ok(rec)
        if rec.t < self.last_t - late:
            return [self._skip(no, f"t={rec.t:g} goes back in time (previous {self.last_t:g})")]
        self.window.append((no, rec))
        if rec.t < self.run_max - late:
            self.conflicted = True
        elif rec.t > self.run_max:
            self.run_max = rec.t
        if len(self.window) <= HOLD_LINES:
            return []
        if not self.conflicted:
            # the window in order (nearly every line): its oldest record is given on
            no_old, old = self.window.popleft()
            if old.t > self.last_t:
                self.last_t = old.t
            return [(no_old, old)]
        return [self._leave()]

    def finish(self) -> list[tuple[int, Record | Skipped]]:
        return [self._leave() for _ in range(len(self.window))]

    def _leave(self) -> tuple[int, Record | Skipped]:
        """The oldest record of the window, given on or dropped."""
        no, rec = self.window[0]
        keep = not self.conflicted or self._oldest_in_longest_run()
        self.window.popleft()
        if keep:
            self.last_t = max(self.last_t, rec.t)
        if self.conflicted:
            self._recheck()
        if keep:
            return no, rec
        if rec.t < self.last_t - _late_ok(rec):
            return self._skip(no, f"t={rec.t:g} goes back in time (previous {self.last_t:g})")
        return self._skip(no, f"t={rec.t:g} is far out of line with the lines around it")

    def _recheck(self) -> None:
        run = self.last_t
        for _, r in self.window:
            if r.t < run - _late_ok(r):
                return
            run = max(run, r.t)
        self.conflicted, self.run_max = False, run

    def _oldest_in_longest_run(self) -> bool:
        """Whether a longest in-order run of the window (a subsequence, each time at or
        after the latest before it, less its lateness) can start with the oldest record."""
        items = [r for _, r in self.window]
        n = len(items)
        best = [0] * n  # longest run ending at j, over any start
        top = [0.0] * n  # the latest time in that run
        best0 = [0] * n  # the same, for runs that start with the oldest
        top0 = [0.0] * n
        for j, r in enumerate(items):
            late = _late_ok(r)
            if r.t < self.last_t - late:
                continue  # behind what was given on: in no run
            best[j], top[j] = 1, r.t
            if j == 0:
                best0[0], top0[0] = 1, r.t
            for i in range(j):
                if best[i] and r.t >= top[i] - late and best[i] + 1 > best[j]:
                    best[j], top[j] = best[i] + 1, max(top[i], r.t)
                if best0[i] and r.t >= top0[i] - late and best0[i] + 1 > best0[j]:
                    best0[j], top0[j] = best0[i] + 1, max(top0[i], r.t)
        return max(best0) >= max(best) > 0


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
            kind = obj.get("type") if isinstance(obj, dict) else None
            if kind == "estimate":
                t_tick = obj.get("t")
                if isinstance(t_tick, bool) or not isinstance(t_tick, float | int):
                    continue
                if not (math.isfinite(t_tick) and abs(t_tick) <= MAX_ABS_T):
                    raise ValueError(f"estimate line with an impossible time {t_tick!r:.20}")
                rec = Tick(float(t_tick))  # where the daemon stepped its filter
            elif isinstance(kind, str) and kind in LOG_ONLY_TYPES:  # a list is unhashable
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


class MeasurementStream:
    """A measurement log read as it is iterated: its header at once (a file that is no
    log is refused before anything is replayed), then its records one at a time, so a
    day's log costs the memory of a window of lines, not of the day.  The lines skipped
    are in ``skipped`` as iteration passes them."""

    def __init__(self, path: str | Path, strict: bool = False) -> None:
        self.path = Path(path)
        self.strict = strict
        self.skipped: list[Skipped] = []
        try:
            self._fh = files.open_regular(self.path)
        except files.FileRefused as exc:
            raise LogError(str(exc)) from None
        try:
            first = self._fh.readline(MAX_LINE_CHARS)
            if not first:
                raise LogError(f"{self.path}: empty file, expected a measurement log header")
            try:
                self.header = _check_header(jsonlines.loads(first))
            except jsonlines.DecodeError:
                raise LogError(f"{self.path}: line 1: header is not valid JSON") from None
        except BaseException as exc:
            self._fh.close()
            raise self._named(exc) from None

    def __iter__(self) -> Iterator[Record]:
        try:
            with self._fh:
                for _, item in iter_lines(_bounded_lines(self._fh), self.strict):
                    if isinstance(item, Skipped):
                        self.skipped.append(item)
                    else:
                        yield item
        except (OSError, LogError) as exc:
            raise self._named(exc) from None

    def _named(self, exc: BaseException) -> BaseException:
        p = self.path
        if isinstance(exc, OSError):
            return LogError(f"{p}: cannot read ({exc.strerror or exc.__class__.__name__})")
        if isinstance(exc, LogError):
            msg = str(exc)
            return LogError(msg if msg.startswith(str(p)) else f"{p}: {msg}")
        return exc


def read_measurement_log(path: str | Path, strict: bool = False) -> MeasurementLog:
    """The whole log in memory (the tools that look at it more than once)."""
    stream = MeasurementStream(path, strict)
    records = list(stream)
    return MeasurementLog(stream.header, records, stream.skipped)


def record_to_json(rec: Record) -> JsonObject:
    out: JsonObject = {"type": TYPE_NAMES[type(rec)]}
    for f in fields(rec):
        v = getattr(rec, f.name)
        if v is None:
            continue
        out[f.name] = v
    return out


class MeasurementWriter:
    """Writes a measurement log v1 to an open text stream."""

    def __init__(self, fh: IO[str], start_utc: str, **extra: object) -> None:
        self._fh = fh
        header = {"format": FORMAT, "version": VERSION, "start_utc": start_utc, **extra}
        fh.write(jsonlines.dumps_line(header))

    def write(self, rec: Record) -> None:
        self._fh.write(jsonlines.dumps_line(record_to_json(rec)))
