"""What a vehicle sends over zenoh, in bytes: is a radio link big enough?

Reads a daemon log (after ``make demo``: out/demo/vehicle/log/navd-*.jsonl), encodes
each estimate, health and advisory exactly as the publisher does (with ``t_utc`` on
estimates), and prints the mean message size and the bytes per second at the rates
they are published, against what a 9600-baud serial radio carries (8N1: 960 B/s).

    python -m bench.link_size LOG [--write BENCHMARKS.md]
"""

from __future__ import annotations

import argparse
import statistics
import sys

from bench.common import report
from navd.daemon.publish import encode
from navd.formats import jsonlines

RATES_HZ = {"estimate": 10.0, "estimate_1hz": 1.0, "health": 1.0, "advisory": 1.0}
RADIO_BPS = 9600 / 10  # bytes a second through a 9600-baud 8N1 link
T_UTC = "2026-12-01T08:00:00.000+00:00"  # what the daemon adds, at its length


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("log", help="a daemon log (JSON Lines)")
    p.add_argument("--write", help="put the result into this BENCHMARKS.md")
    args = p.parse_args(argv)
    sizes: dict[str, list[int]] = {"estimate": [], "health": [], "advisory": []}
    with open(args.log, "rb") as fh:
        for seq, line in enumerate(fh):
            try:
                o = jsonlines.loads(line)
            except jsonlines.DecodeError:
                continue
            kind = o.get("type") if isinstance(o, dict) else None
            if kind in sizes:
                body = {**o, "t_utc": T_UTC} if kind == "estimate" else o
                sizes[kind].append(len(encode(seq, body)))
    if not sizes["estimate"]:
        print(f"{args.log}: no estimates: not a daemon log?", file=sys.stderr)
        return 2
    sizes["estimate_1hz"] = sizes["estimate"]
    rows = [
        "`python -m bench.link_size out/demo/vehicle/log/navd-*.jsonl` (after `make demo`): "
        "zenoh payloads as navd publishes them, before zenoh's own framing.",
        "",
        "| key | messages | mean bytes | rate | bytes/s | share of a 9600-baud radio |",
        "|---|---|---|---|---|---|",
    ]
    for kind, hz in RATES_HZ.items():
        xs = sizes[kind]
        if not xs:
            continue
        mean = statistics.fmean(xs)
        n = f"{len(xs)} (the estimates, 1 in 10)" if kind == "estimate_1hz" else len(xs)
        rows.append(
            f"| {kind} | {n} | {mean:.0f} | {hz:g} Hz | {mean * hz:.0f} | "
            f"{mean * hz / RADIO_BPS:.0%} |"
        )
    report("\n".join(rows), args.write, "bench-link-size", "Zenoh message sizes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
