"""Two Monte Carlo runs of the same seeds, compared mission by mission.

    python -m bench.compare_missions BEFORE.jsonl AFTER.jsonl [--from-seed N]

BEFORE and AFTER are ``python -m bench.robustness --missions-out`` files.  Per class, per
geometry (a single moving beacon, or a net of 2 or 3 transponders) and over all: the RMS
over the bound as the robustness table takes it, the truth inside the 95 % ellipse (mean
of ``inside95``), the geometric mean of the per-mission RMS ratio, the missions more than
5 % better or worse, the truth inside the 99 % ellipse while ``ok`` (mean of
``ok_inside99`` over the missions that were ever ``ok``), the missions whose ``ok`` held
the truth outside it more than 3 % of the time, and the divergences; then the largest
changes.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from typing import Any

_SIGNIFICANT = math.log(1.05)  # a mission more than 5 % better or worse


def load(path: str) -> dict[int, dict[str, Any]]:
    """The file's missions by seed, those whose default replay produced a score."""
    out: dict[int, dict[str, Any]] = {}
    with open(path, encoding="utf-8") as fh:
        for row in map(json.loads, fh):
            if row.get("default"):
                out[int(row["seed"])] = row
    return out


def _rms(xs: list[float]) -> float:
    return math.sqrt(sum(x * x for x in xs) / len(xs))


def _false_ok(row: dict[str, Any]) -> bool:
    v = row["default"]["ok_inside99"]
    return v is not None and not math.isnan(v) and v < 0.97


_GEOMETRY = {"beacon": "single beacon", "lbl-2": "2-transponder", "lbl-3": "3-transponder"}


def _ok99(row: dict[str, Any]) -> float | None:
    v = row["default"]["ok_inside99"]
    return None if v is None or math.isnan(v) else float(v)


def _mean_ok99(rows: list[dict[str, Any]]) -> str:
    vs = [v for v in map(_ok99, rows) if v is not None]
    return f"{sum(vs) / len(vs):.3f}" if vs else "-"


def compare(before: dict[int, dict[str, Any]], after: dict[int, dict[str, Any]]) -> list[str]:
    seeds = sorted(set(before) & set(after))
    groups: dict[str, list[int]] = defaultdict(list)
    for s in seeds:
        groups[before[s]["class"]].append(s)
    for s in seeds:  # after the classes, so that the geometries' rows follow theirs
        kind = str(before[s].get("kind"))
        groups[_GEOMETRY.get(kind, kind)].append(s)
    groups["all"] = seeds
    lines = [
        "| class | missions | / bound before | after | in95 before | after | ratio "
        "| better / worse | ok in99 before | after | false ok before | after "
        "| divergences before | after |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, ss in groups.items():
        bound = _rms([before[s]["bound_m"] for s in ss])
        logs = [
            math.log(after[s]["default"]["rms_m"] / before[s]["default"]["rms_m"]) for s in ss
        ]
        cells = [
            f"{_rms([d[s]['default']['rms_m'] for s in ss]) / bound:.2f}" for d in (before, after)
        ]
        cells += [
            f"{sum(d[s]['default']['inside95'] for s in ss) / len(ss):.3f}" for d in (before, after)
        ]
        lines.append(
            f"| {name} | {len(ss)} | {' | '.join(cells)} | "
            f"{math.exp(sum(logs) / len(logs)):.3f} | "
            f"{sum(x < -_SIGNIFICANT for x in logs)} / {sum(x > _SIGNIFICANT for x in logs)} | "
            f"{_mean_ok99([before[s] for s in ss])} | {_mean_ok99([after[s] for s in ss])} | "
            f"{sum(_false_ok(before[s]) for s in ss)} | {sum(_false_ok(after[s]) for s in ss)} | "
            f"{sum(bool(before[s].get('diverged')) for s in ss)} | "
            f"{sum(bool(after[s].get('diverged')) for s in ss)} |"
        )
    moved = sorted(
        seeds,
        key=lambda s: after[s]["default"]["rms_m"] ** 2 - before[s]["default"]["rms_m"] ** 2,
    )
    for label, picked in (("largest gains", moved[:5]), ("largest losses", moved[-5:][::-1])):
        lines.append(f"{label}: " + ", ".join(
            f"seed {s} ({before[s]['class']}, {before[s]['default']['rms_m']:.0f} -> "
            f"{after[s]['default']['rms_m']:.0f} m, in95 {before[s]['default']['inside95']:.2f}"
            f" -> {after[s]['default']['inside95']:.2f})"
            for s in picked
        ))
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before")
    p.add_argument("after")
    p.add_argument("--from-seed", type=int, default=1, help="only seeds from this one on")
    args = p.parse_args(argv)
    try:
        before, after = load(args.before), load(args.after)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"compare_missions: {exc.__class__.__name__}: {exc}") from None
    keep = {s for s in before if s >= args.from_seed}
    before = {s: r for s, r in before.items() if s in keep}
    if not set(before) & set(after):
        raise SystemExit("compare_missions: the two files share no seeds")
    print("\n".join(compare(before, after)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
