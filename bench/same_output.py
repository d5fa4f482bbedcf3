"""``python -m bench.same_output A B --tolerance T``: two replay outputs line for line, the
same types and keys, every number within T (relative, or absolute below 1), every other
value equal.  What ``make check-armhf`` holds an ARM board's replay to."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from navd.formats import jsonlines


def differences(a: list[dict[str, Any]], b: list[dict[str, Any]], tol: float) -> list[str]:
    if len(a) != len(b):
        return [f"{len(a)} lines against {len(b)}"]
    out = []
    for no, (x, y) in enumerate(zip(a, b, strict=True), start=1):
        if x.keys() != y.keys():
            out.append(f"line {no}: keys {sorted(x.keys() ^ y.keys())} differ")
            continue
        for k, u in x.items():
            v = y[k]
            if isinstance(u, float) or isinstance(v, float):
                numbers = isinstance(u, int | float) and isinstance(v, int | float)
                if not (numbers and math.isclose(u, v, rel_tol=tol, abs_tol=tol)):
                    out.append(f"line {no}: {k} {u!r} against {v!r}")
            elif u != v:
                out.append(f"line {no}: {k} {u!r} against {v!r}")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--tolerance", type=float, default=1e-9)
    args = p.parse_args()
    a, b = jsonlines.read(args.a), jsonlines.read(args.b)
    diff = differences(a, b, args.tolerance)
    identical = not diff and Path(args.a).read_bytes() == Path(args.b).read_bytes()
    for d in diff[:20]:
        print(d)
    verdict = "identical" if identical else ("within" if not diff else "NOT within")
    print(f"{args.a} and {args.b}: {len(a)} lines, {verdict} {args.tolerance:g}")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
