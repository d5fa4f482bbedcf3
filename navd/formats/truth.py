"""The simulator's truth (``truth.jsonl``): one sample a simulator step, written by
``navd-sim`` and read by scoring, reports and the benches.

The reader refuses a file that is not one, naming the line: an output or a log
handed over by mistake has most of these fields too, and a ``type``, which a
truth sample has not.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, fields
from operator import attrgetter
from pathlib import Path
from typing import IO

from navd.formats import jsonlines


class TruthError(ValueError):
    """A file that is not the simulator's truth; the message names it and the line."""


@dataclass(frozen=True, slots=True)
class TruthSample:
    t: float
    lat: float
    lon: float
    depth: float
    heading_deg: float  # true
    speed_mps: float  # through the water
    current_n: float
    current_e: float
    boat_lat: float
    boat_lon: float


FIELDS = tuple(f.name for f in fields(TruthSample))
_values = attrgetter(*FIELDS)  # asdict's deep copy, without its cost per sample


def write_truth(fh: IO[str], samples: Iterable[TruthSample]) -> None:
    fh.writelines(
        jsonlines.dumps_line(dict(zip(FIELDS, _values(s), strict=True))) for s in samples
    )


def _sample(obj: object) -> TruthSample | None:
    row = jsonlines.object_or_none(obj)
    if row is None or "type" in row:
        return None
    values = [row.get(k) for k in FIELDS]
    numbers = [float(v) for v in values if isinstance(v, int | float) and not isinstance(v, bool)]
    return TruthSample(*numbers) if len(numbers) == len(FIELDS) else None


def read_truth(path: str | Path) -> list[TruthSample]:
    """Every sample of a truth file; raises TruthError naming the first line that is
    not one, or a file without any."""
    out: list[TruthSample] = []
    with open(path, "rb") as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                s = _sample(jsonlines.loads(line))
            except jsonlines.DecodeError:
                raise TruthError(f"{path}: line {n}: not JSON") from None
            if s is None:
                raise TruthError(
                    f"{path}: line {n} is not a truth sample (it needs "
                    f"{', '.join(FIELDS)}: the simulator's truth.jsonl)"
                )
            out.append(s)
    if not out:
        raise TruthError(f"{path}: no truth samples")
    return out
