"""What reading a log costs navd before it navigates: ``make bench-replay``'s budget line.

``python -m bench.log_read LOG`` starts as ``navd replay`` does, then reads and checks every
record of LOG with navd's own reader (navd.formats.mlog: the header, each line's fields
and bounds, the time rules) and nothing else: no filter, no output.  Set beside the
numpy floor, it shows how much of the floor's time navd's input checks alone take.
"""

from __future__ import annotations

import sys

import navd.cli  # noqa: F401  (replay's start-up: its imports, as `navd replay` pays them)
from navd.formats.mlog import LogError, MeasurementStream


def main(log: str) -> int:
    try:
        stream = MeasurementStream(log)
        n = sum(1 for _ in stream)
    except LogError as exc:
        print(f"log_read: {exc}", file=sys.stderr)
        return 1
    print(f"{n} records, {len(stream.skipped)} lines skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]) if len(sys.argv) == 2 else 2)
