"""The daemon's append-only, crash-safe, size-rotated log.

Every measurement record fed to the filter (stamped with its monotonic arrival
time), every raw byte off a serial port, every estimate and range decision goes
into JSON Lines files that are a measurement log v1 (header ``time_base:
monotonic``), so ``navd replay`` reads them as they are.  Lines are buffered and
handed to the kernel every ``flush_s`` (a quarter second), so a ``kill -9`` loses at
most that much (the requirement is one second) without a system call per line;
``fsync`` every ``fsync_s`` bounds what a power cut can lose.  A full or failing
disk degrades logging (counted, said in health) and never stops navigation.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TextIO

from navd.formats import jsonlines
from navd.formats.mlog import FORMAT, VERSION, record_to_json
from navd.records import Record
from navd.schema import LOG_TYPE, Published, to_dict

_RETRY_AFTER_S = 10.0


class RecordLog:
    def __init__(
        self,
        directory: str | Path,
        rotate_mb: float = 64.0,
        raw: bool = True,
        raw_budget_bytes_per_s: float = 20_000.0,
        keep_mb: float = 0.0,
    ) -> None:
        self.dir = Path(directory)
        self.rotate_bytes = int(rotate_mb * 1024 * 1024)
        self.keep_bytes = int(keep_mb * 1024 * 1024)
        self.raw = raw
        self.raw_budget = raw_budget_bytes_per_s
        # per device: (bytes still allowed, time of the last refill); excess is counted
        self._raw_allow: dict[str, tuple[float, float]] = {}
        self.raw_dropped: dict[str, int] = {}
        self.removed_files = 0
        self.fh: TextIO | None = None
        self.path: Path | None = None
        # told each file's header as it is written (the daemon reads its clock from it,
        # as a replay of the file will)
        self.on_header: Callable[[Mapping[str, object]], None] | None = None
        self.size = 0
        self.files = 0
        self.lines = 0
        self.errors = 0
        self.dropped = 0
        self.last_error = ""
        self._retry_at = 0.0

    @property
    def degraded(self) -> bool:
        return self.fh is None

    def _open(self) -> None:
        self.dir.mkdir(parents=True, exist_ok=True)
        self._retain()
        now = dt.datetime.now(dt.UTC)
        self.files += 1
        self.path = self.dir / f"navd-{now:%Y%m%dT%H%M%S}-{os.getpid()}-{self.files:03d}.jsonl"
        fh = self.path.open("a", encoding="utf-8", buffering=1 << 16)
        header = {
            "format": FORMAT,
            "version": VERSION,
            "start_utc": now.strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
            "time_base": "monotonic",
            "start_monotonic": time.monotonic(),
        }
        line = jsonlines.dumps_line(header)
        fh.write(line)
        fh.flush()
        self.fh, self.size = fh, len(line)
        if self.on_header is not None:
            self.on_header(header)

    def _write(self, obj: Mapping[str, object]) -> None:
        if self.fh is None:
            if time.monotonic() < self._retry_at:
                self.dropped += 1
                return
            try:
                self._open()
            except OSError as exc:
                self._fail(exc)
                self.dropped += 1
                return
        fh = self.fh
        if fh is None:
            return  # pragma: no cover - _open either set it or raised
        try:
            line = jsonlines.dumps_line(obj)
            fh.write(line)
        except (OSError, ValueError, TypeError) as exc:
            self._fail(exc)
            self.dropped += 1
            return
        self.lines += 1
        self.size += len(line)
        if self.size >= self.rotate_bytes:
            self.close()

    def _fail(self, exc: Exception) -> None:
        self.errors += 1
        self.last_error = f"{exc.__class__.__name__}: {exc}"
        self._retry_at = time.monotonic() + _RETRY_AFTER_S
        if self.fh is not None:
            with contextlib.suppress(OSError):
                self.fh.close()
        self.fh = None

    def section(self) -> dict[str, object]:
        """The log's part of the daemon's health."""
        return {
            "file": str(self.path) if self.path else None,
            "ok": not (self.degraded and self.errors),
            "lines": self.lines,
            "errors": self.errors,
            "dropped": self.dropped,
            "raw_bytes_over_budget": dict(self.raw_dropped),
            "files_removed": self.removed_files,
            "last_error": self.last_error,
        }

    def record(self, rec: Record) -> None:
        self._write(record_to_json(rec))

    def raw_bytes(self, t: float, device: str, data: bytes) -> None:
        if not self.raw:
            return
        # a token bucket of one second's budget: bursts pass, a babbling device does not
        allow, t_last = self._raw_allow.get(device, (self.raw_budget, t))
        allow = min(self.raw_budget, allow + max(0.0, t - t_last) * self.raw_budget)
        if len(data) > allow:
            self._raw_allow[device] = (allow, t)
            self.raw_dropped[device] = self.raw_dropped.get(device, 0) + len(data)
            return
        self._raw_allow[device] = (allow - len(data), t)
        self._write({"type": "raw", "t": t, "device": device, "hex": data.hex()})

    def _retain(self) -> None:
        """Remove the oldest log files while the directory holds more than ``keep_mb``."""
        if self.keep_bytes <= 0:
            return
        try:
            files = sorted(self.dir.glob("navd-*.jsonl"), key=lambda f: f.stat().st_mtime)
            total = sum(f.stat().st_size for f in files)
        except OSError:
            return  # a file vanished under us: try again at the next rotation
        for f in files:
            if total <= self.keep_bytes:
                break
            try:
                size = f.stat().st_size
                f.unlink()
            except OSError:
                continue
            total -= size
            self.removed_files += 1

    def output(self, out: Published) -> None:
        line = to_dict(out)
        # filter outputs are logged under their own names so the log stays a measurement log
        if out.type in LOG_TYPE:
            line["type"] = LOG_TYPE[out.type]
        self._write(line)

    def flush(self) -> None:
        """Hand buffered lines to the kernel: from here a crash of navd loses nothing."""
        if self.fh is None:
            return
        try:
            self.fh.flush()
        except OSError as exc:
            self._fail(exc)

    def sync(self) -> None:
        """Flush and fsync: from here a power cut loses nothing."""
        self.flush()
        if self.fh is None:
            return
        try:
            os.fsync(self.fh.fileno())
        except OSError as exc:
            self._fail(exc)

    def close(self) -> None:
        if self.fh is not None:
            try:
                self.fh.flush()
                os.fsync(self.fh.fileno())
                self.fh.close()
            except OSError:
                pass
        self.fh = None
