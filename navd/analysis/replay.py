"""``navd replay``: the daemon's filter over a recorded log, as fast as the CPU goes.

The contract is ``shared/spec/replay-interface.md``; the formats are documented in
``docs/replay.md``.
"""

from __future__ import annotations

import io
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from navd.config import Config, ConfigError
from navd.filter import Navigator
from navd.formats import jsonlines
from navd.formats.mlog import LogError, MeasurementLog, Skipped, read_measurement_log

MAX_REPORTED_SKIPS = 20


@dataclass(slots=True)
class ReplayResult:
    outputs: list[dict[str, Any]]
    skipped: list[Skipped]
    counters: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    # with smoothing, the estimates as the filter made them (outputs has them smoothed)
    filtered: list[dict[str, Any]] = field(default_factory=list)


def run_navigator(log: MeasurementLog, cfg: Config, smooth: bool = False) -> ReplayResult:
    if smooth and cfg.navigation.filter == "vlbl":
        # VLBL's fixes replace the state rather than update it: there is nothing to smooth
        raise ConfigError("navigation.filter: --smooth needs a Kalman mode (default or thesis)")
    nav = Navigator(cfg, keep_history=smooth)
    outputs: list[dict[str, Any]] = []
    for rec in log.records:
        outputs.extend(nav.feed(rec))
    if log.records:
        outputs.extend(nav.advance(log.records[-1].t))
    filtered: list[dict[str, Any]] = []
    if smooth:
        filtered = outputs
        smoothed = iter(nav.smoothed())
        outputs = [next(smoothed) if o["type"] == "estimate" else o for o in outputs]
    return ReplayResult(outputs, log.skipped, dict(nav.counters), nav.warnings, filtered)


def write_outputs(outputs: list[dict[str, Any]], fh: IO[str]) -> None:
    fh.writelines(jsonlines.dumps_line(o) for o in outputs)


def _is_empty(path: str | Path) -> bool:
    try:
        return Path(path).stat().st_size == 0
    except OSError:
        return False  # the reader says why it cannot open it


def replay(
    input_path: str | Path | list[str | Path],
    cfg: Config,
    out_path: str | Path,
    smooth: bool = False,
    strict: bool = False,
    err: IO[str] = sys.stderr,
) -> ReplayResult:
    """Replay one log, or the consecutive files of a rotated daemon log, as one mission."""
    paths = input_path if isinstance(input_path, list) else [input_path]
    log = MeasurementLog({}, [], [])
    for path in paths:
        if len(paths) > 1 and _is_empty(path):
            # a daemon that hit a full disk can leave an empty file among its logs
            print(f"{path}: empty file, passed over", file=err)
            continue
        part = read_measurement_log(path, strict=strict)
        log.header = log.header or part.header
        log.records.extend(part.records)
        log.skipped.extend(part.skipped)
        for s in part.skipped[:MAX_REPORTED_SKIPS]:
            print(f"{path}: line {s.line}: skipped: {s.reason}", file=err)
        if len(part.skipped) > MAX_REPORTED_SKIPS:
            print(
                f"{path}: ... {len(part.skipped) - MAX_REPORTED_SKIPS} more lines skipped", file=err
            )
    result = run_navigator(log, cfg, smooth)
    for w in result.warnings:
        print(f"warning: {w}", file=err)
    out = Path(out_path)
    tmp = out.with_name(out.name + ".part")
    with tmp.open("w", encoding="utf-8") as fh:
        write_outputs(result.outputs, fh)
    tmp.replace(out)
    c = result.counters
    n_est = sum(1 for o in result.outputs if o["type"] == "estimate")
    print(
        f"replayed {len(log.records)} records ({len(log.skipped)} lines skipped): "
        f"{n_est} estimates, ranges accepted {c.get('ranges_accepted', 0)}, "
        f"rejected {c.get('ranges_rejected', 0)} -> {out}",
        file=err,
    )
    return result


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


def replay_one(path: str, cfg: Config, out: Path, smooth: bool, strict: bool) -> str:
    """One mission of ``--each``: what ``navd replay PATH`` would print, as text (a worker
    process sends back this, not the outputs)."""
    err = io.StringIO()
    try:
        replay(path, cfg, out, smooth=smooth, strict=strict, err=err)
    except (ConfigError, LogError) as exc:
        err.write(f"navd: {exc}\n")
    return err.getvalue()
