"""``navd replay``: the daemon's filter over a recorded log, as fast as the CPU goes.

The contract is ``shared/spec/replay-interface.md``; the formats are documented in
``docs/replay.md``.
"""

from __future__ import annotations

import io
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from navd.files import written_whole
from navd.filter import Navigator
from navd.formats import jsonlines
from navd.formats.mlog import LogError, MeasurementLog, MeasurementStream, Skipped, log_epoch
from navd.records import Record
from navd.schema import Estimate, Output, to_dict
from navd.settings import Config, ConfigError

MAX_REPORTED_SKIPS = 20


@dataclass(slots=True)
class ReplayResult:
    outputs: list[Output]
    skipped: list[Skipped]
    counters: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    # with smoothing, the outputs as the filter made them (outputs has them smoothed)
    filtered: list[Output] = field(default_factory=list)


@dataclass(slots=True)
class ReplaySummary:
    """What a streamed replay says when it is done (its outputs are in the file)."""

    records: int
    skipped: int
    estimates: int
    counters: dict[str, int]
    warnings: list[str]


def _check_smoothable(cfg: Config, smooth: bool) -> None:
    if smooth and cfg.navigation.filter == "vlbl":
        # VLBL's fixes replace the state rather than update it: there is nothing to smooth
        raise ConfigError("navigation.filter: --smooth needs a Kalman mode (default or thesis)")


def navigate(
    nav: Navigator, records: Iterable[Record], checked: bool = False
) -> Iterator[Output]:
    """The navigator's outputs over the records, as they come, up to the last record.

    ``checked``: every record has passed :func:`navd.records.implausible` (a log
    reader's records have)."""
    last: Record | None = None
    feed = nav.feed
    for rec in records:
        last = rec
        yield from feed(rec, checked)
    if last is not None:
        yield from nav.advance(last.t)


def _smoothed(nav: Navigator, outputs: Iterable[Output]) -> Iterator[Output]:
    """The forward pass's outputs with each estimate replaced by its smoothed one.

    The forward pass runs to its end first; of its outputs only what is not an
    estimate is held (a few per ping), with the number of estimates before it."""
    others: list[tuple[int, Output]] = []
    n = 0
    for o in outputs:
        if isinstance(o, Estimate):
            n += 1
        else:
            others.append((n, o))
    pending = iter(others)
    nxt = next(pending, None)
    for i, est in enumerate(nav.smoothed()):
        while nxt is not None and nxt[0] == i:
            yield nxt[1]
            nxt = next(pending, None)
        yield est
    while nxt is not None:
        yield nxt[1]
        nxt = next(pending, None)


def run_navigator(log: MeasurementLog, cfg: Config, smooth: bool = False) -> ReplayResult:
    _check_smoothable(cfg, smooth)
    nav = Navigator(cfg, keep_history=smooth)
    nav.set_clock(log_epoch(log.header))
    outputs = list(navigate(nav, log.records))
    filtered: list[Output] = []
    if smooth:
        filtered, outputs = outputs, list(_smoothed(nav, outputs))
    return ReplayResult(outputs, log.skipped, dict(nav.counters), nav.warnings, filtered)


def write_outputs(outputs: Iterable[Output], fh: IO[str]) -> None:
    fh.writelines(jsonlines.dumps_line(to_dict(o)) for o in outputs)


def _is_empty(path: str | Path) -> bool:
    try:
        return Path(path).stat().st_size == 0
    except OSError:
        return False  # the reader says why it cannot open it


class _Logs:
    """The records of one log, or of the consecutive files of a rotated daemon log, as
    one stream; each file's skipped lines are said when the file is done."""

    def __init__(
        self, paths: list[str | Path], strict: bool, err: IO[str], nav: Navigator
    ) -> None:
        self.err = err
        self.nav = nav
        self.records = 0
        self.skipped = 0
        # every file is opened (its header checked) before anything is replayed
        self.streams = [
            MeasurementStream(p, strict) for p in paths if not self._passed_over(p, len(paths))
        ]

    def _passed_over(self, path: str | Path, n: int) -> bool:
        if n > 1 and _is_empty(path):
            # a daemon that hit a full disk can leave an empty file among its logs
            print(f"{path}: empty file, passed over", file=self.err)
            return True
        return False

    def __iter__(self) -> Iterator[Record]:
        for stream in self.streams:
            # each file's own clock: a daemon's restart starts a new monotonic count
            self.nav.set_clock(log_epoch(stream.header))
            for rec in stream:
                self.records += 1
                yield rec
            self.skipped += len(stream.skipped)
            self._say_skipped(stream)

    def _say_skipped(self, stream: MeasurementStream) -> None:
        path, skipped = stream.path, stream.skipped
        for s in skipped[:MAX_REPORTED_SKIPS]:
            print(f"{path}: line {s.line}: skipped: {s.reason}", file=self.err)
        if len(skipped) > MAX_REPORTED_SKIPS:
            more = len(skipped) - MAX_REPORTED_SKIPS
            print(f"{path}: ... {more} more lines skipped", file=self.err)


def _replayed(nav: Navigator, logs: _Logs, smooth: bool) -> Iterator[Output]:
    """What a replay writes, output by output (with the smoother's temporary files
    closed when it is done, or given up)."""
    try:
        outputs: Iterable[Output] = navigate(nav, logs, checked=True)
        if smooth:
            outputs = _smoothed(nav, outputs)
        yield from outputs
    finally:
        if nav.smoothing is not None:
            nav.smoothing.close()  # its temporary files, now rather than at collection


def replay_outputs(input_path: str | Path, cfg: Config, smooth: bool = False) -> list[Output]:
    """What :func:`replay` writes, as the outputs themselves: for a worker that replays
    hundreds of missions and scores them (no file written and read back)."""
    _check_smoothable(cfg, smooth)
    nav = Navigator(cfg, keep_history=smooth)
    return list(_replayed(nav, _Logs([input_path], False, io.StringIO(), nav), smooth))


def replay(
    input_path: str | Path | list[str | Path],
    cfg: Config,
    out_path: str | Path,
    smooth: bool = False,
    strict: bool = False,
    err: IO[str] | None = None,
) -> ReplaySummary:
    """Replay one log, or the consecutive files of a rotated daemon log, as one mission.

    Records are read, filtered and written as they come, so memory does not grow with
    the mission.  The smoother needs every step before it can write the first: with it
    the steps and estimates wait on disk (navd/filter/smoothing.py), and only the range
    decisions in memory.
    """
    _check_smoothable(cfg, smooth)
    err = err or sys.stderr  # looked up now: a test or a caller may have replaced it
    nav = Navigator(cfg, keep_history=smooth)
    logs = _Logs(input_path if isinstance(input_path, list) else [input_path], strict, err, nav)
    out = Path(out_path)
    estimates = 0
    # a strict replay stopped by a bad line leaves nothing
    with written_whole(out) as fh:
        for o in _replayed(nav, logs, smooth):
            estimates += isinstance(o, Estimate)
            fh.write(jsonlines.dumps_line(to_dict(o)))
    for w in nav.warnings:
        print(f"warning: {w}", file=err)
    c = nav.counters
    print(
        f"replayed {logs.records} records ({logs.skipped} lines skipped): "
        f"{estimates} estimates, ranges accepted {c.get('ranges_accepted', 0)}, "
        f"rejected {c.get('ranges_rejected', 0)} -> {out}",
        file=err,
    )
    return ReplaySummary(logs.records, logs.skipped, estimates, dict(c), list(nav.warnings))


def outputs_for_each(inputs: list[str], out_dir: str | Path) -> list[Path]:
    """Where ``--each`` writes each log's output: ``DIR/<log's stem>.out.jsonl``, or with
    its directory's name in front where two logs share a stem (``mc-1/measurements.jsonl``)."""
    stems = [Path(p).stem for p in inputs]
    names = [
        f"{Path(p).resolve().parent.name}-{st}" if stems.count(st) > 1 else st
        for p, st in zip(inputs, stems, strict=True)
    ]
    for i, n in enumerate(names):
        if n in names[:i]:
            other = inputs[names.index(n)]
            raise ConfigError(
                f"--each: {other} and {inputs[i]} would both write {n}.out.jsonl; "
                "replay them apart"
            )
    return [Path(out_dir) / f"{n}.out.jsonl" for n in names]


def replay_one(
    path: str, cfg: Config, out: Path, smooth: bool, strict: bool
) -> tuple[bool, str]:
    """One mission of ``--each``: whether it was replayed, and what ``navd replay PATH``
    would print (a worker process sends back this, not the outputs)."""
    err = io.StringIO()
    try:
        replay(path, cfg, out, smooth=smooth, strict=strict, err=err)
    except (ConfigError, LogError) as exc:
        err.write(f"navd: {exc}\n")
        return False, err.getvalue()
    return True, err.getvalue()
