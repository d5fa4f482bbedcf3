"""The estimates and range decisions of a replay output or a daemon log, read once into
their dataclasses for the tools that come after a mission (report, scoring)."""

from __future__ import annotations

from pathlib import Path

from navd.formats import jsonlines
from navd.formats.mlog import LogError
from navd.schema import Output, output_of


def read_outputs(path: str | Path) -> list[Output]:
    """Every estimate and range decision in the file, in its order; other lines (the
    measurements and health of a daemon log) are passed over.  A line that is not JSON,
    or an estimate or decision without its fields, is a :class:`LogError` naming it."""
    out: list[Output] = []
    with open(path, "rb") as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                row = jsonlines.loads(line)
            except jsonlines.DecodeError:
                raise LogError(f"{path}: line {n}: not JSON") from None
            if not isinstance(row, dict):
                continue
            got = output_of(row)
            if isinstance(got, str):
                raise LogError(f"{path}: line {n}: {got}")
            if got is not None:
                out.append(got)
    return out
