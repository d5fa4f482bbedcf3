"""``python -m bench.live_log_ok LOG...``: did a daemon that ran against the emulators
navigate?  Its log must hold at least 300 estimates at 10 Hz, health lines, every device
connected in the last one (an estimate at all means a GPS fix started the filter)."""

from __future__ import annotations

import sys

from navd.formats import jsonlines

_MIN_ESTIMATES = 300


def verdict(lines: list[dict]) -> list[str]:
    est = [o for o in lines if o.get("type") == "estimate"]
    health = [o for o in lines if o.get("type") == "health"]
    problems = []
    if len(est) < _MIN_ESTIMATES:
        problems.append(f"{len(est)} estimates, fewer than {_MIN_ESTIMATES}")
    if not health:
        problems.append("no health line")
    else:
        off = [n for n, d in health[-1].get("devices", {}).items() if not d.get("connected")]
        if off:
            problems.append(f"devices not connected at the end: {', '.join(off)}")
    return problems


def summary(lines: list[dict]) -> str:
    modes: dict[str, int] = {}
    for o in lines:
        if o.get("type") == "estimate":
            modes[o.get("mode", "?")] = modes.get(o.get("mode", "?"), 0) + 1
    health = [o for o in lines if o.get("type") == "health"]
    last = health[-1] if health else {}
    said = "ok" if last.get("ok") else f"degraded: {', '.join(last.get('degraded', []))}"
    by_mode = ", ".join(f"{k} {v}" for k, v in sorted(modes.items()))
    return f"estimates by mode: {by_mode}; last health {said}"


def main() -> int:
    lines = [o for path in sys.argv[1:] for o in jsonlines.read(path)]
    problems = verdict(lines)
    for p in problems:
        print(f"live_log_ok: {p}")
    print(f"live_log_ok: {summary(lines)}" + ("" if problems else "; passed"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
