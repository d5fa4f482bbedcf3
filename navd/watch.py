"""``navd watch``: the live estimate for a person, built on :mod:`navd.client`.

One vehicle: a line per estimate (at most every ``--every`` seconds) and per range
decision.  ``--fleet``: every vehicle under ``auv/*`` a line each second, and a line
when a daemon comes up or goes away (its liveliness token).
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque

import zenoh

from navd.client import NavClient, NavFleet, NavUnavailable, endpoints
from navd.schema import Advisory, Estimate, RangeDecision
from navd.settings import Config


def format_estimate(e: Estimate) -> str:
    return (
        f"{e.mode:9s} {e.lat:11.7f} {e.lon:12.7f} depth {e.depth:5.2f} m  "
        f"1-sigma {e.std_n:5.1f}/{e.std_e:5.1f} m  current "
        f"{e.current_n:+.2f}N {e.current_e:+.2f}E m/s  {e.integrity}"
        + ("  calibration priors refuted" if e.calibration_refuted else "")
    )


def format_advisory(a: Advisory) -> str:
    if a.verdict == "ok":
        return f"observability ok ({a.ranges} ranges, bearings over {a.bearing_spread_deg} deg)"
    if a.verdict == "no_ranges":
        return f"observability: no ranges in the last {a.window_s:.0f} s"
    turn = ""
    if a.suggest_heading_deg is not None:
        turn = f": turn {a.suggest_turn_deg:+.0f} deg to {a.suggest_heading_deg:.0f}"
    return (
        f"observability: weak across the line of sight (bearings over "
        f"{a.bearing_spread_deg} deg, axis {a.weak_axis_deg} deg){turn}"
    )


#: how long to wait for the first estimate before asking whether navd is there
FIRST_ESTIMATE_S = 10.0
#: a suggested heading or weak axis that moved less than this is the same advice
ADVICE_STEP_DEG = 10.0


def _angle_moved(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return (a is None) != (b is None)
    return abs((a - b + 180.0) % 360.0 - 180.0) >= ADVICE_STEP_DEG


def advice_changed(prev: Advisory | None, a: Advisory) -> bool:
    """Worth a new line: another verdict, or a turn or axis that moved by 10 degrees.

    The suggested heading follows the estimate and wanders by a degree or two from
    one second to the next; reprinting it then says nothing new.
    """
    if prev is None or prev.verdict != a.verdict:
        return True
    return _angle_moved(prev.suggest_heading_deg, a.suggest_heading_deg) or _angle_moved(
        prev.weak_axis_deg, a.weak_axis_deg
    )


def _endpoints(cfg: Config, connect: list[str] | None) -> list[str]:
    return endpoints(cfg.zenoh.listen, cfg.zenoh.connect, connect)


def watch(
    cfg: Config,
    count: int | None,
    seconds: float | None,
    every: float,
    connect: list[str] | None = None,
    zenoh_file: str | None = None,
) -> int:
    got: deque[Estimate | RangeDecision | Advisory] = deque(maxlen=256)
    wake = threading.Event()
    said: Advisory | None = None  # the last advisory printed: a line when it changes

    def keep(x: Estimate | RangeDecision | Advisory) -> None:
        got.append(x)
        wake.set()

    n = 0
    last_print = 0.0
    t_end = time.monotonic() + seconds if seconds else None
    # no estimate at all this long after the start: ask navd, rather than wait forever
    t_ask: float | None = time.monotonic() + FIRST_ESTIMATE_S
    try:
        nav = NavClient(cfg.vehicle.name, _endpoints(cfg, connect), config_file=zenoh_file)
    except NavUnavailable as exc:
        print(f"navd watch: {exc}", file=sys.stderr)
        return 1
    with nav:
        nav.subscribe(keep, keep, keep)
        try:
            while (count is None or n < count) and (t_end is None or time.monotonic() < t_end):
                wake.wait(0.1)
                wake.clear()
                if t_ask is not None and n == 0 and time.monotonic() > t_ask:
                    t_ask = None
                    try:
                        nav.check()
                    except NavUnavailable as exc:
                        print(f"navd watch: {exc}", file=sys.stderr)
                        return 1
                while got and (count is None or n < count):
                    x = got.popleft()
                    if isinstance(x, Advisory):
                        if advice_changed(said, x):
                            print(format_advisory(x), flush=True)
                            said = x
                        continue
                    if isinstance(x, RangeDecision):
                        verdict = "accepted" if x.accepted else f"rejected ({x.reason})"
                        print(f"range {x.range_m or float('nan'):.1f} m {verdict}", flush=True)
                        continue
                    n += 1
                    now = time.monotonic()
                    if every <= 0 or now - last_print >= every:
                        print(format_estimate(x), flush=True)
                        last_print = now
        except KeyboardInterrupt:
            pass
        if n == 0:
            try:
                nav.check()
                print("navd watch: navd answers, but published no estimate", file=sys.stderr)
            except NavUnavailable as exc:
                print(f"navd watch: {exc}", file=sys.stderr)
            return 1
    return 0


def watch_fleet(
    cfg: Config,
    seconds: float | None,
    every: float,
    connect: list[str] | None = None,
    zenoh_file: str | None = None,
) -> int:
    try:
        fleet = NavFleet(_endpoints(cfg, connect), config_file=zenoh_file)
    except zenoh.ZError as exc:
        print(f"navd watch --fleet: cannot open a zenoh session: {str(exc)[:120]}", file=sys.stderr)
        return 1
    t_end = time.monotonic() + seconds if seconds else None
    up: set[str] = set()
    seen = False
    try:
        while t_end is None or time.monotonic() < t_end:
            time.sleep(max(every, 0.2))
            now_up = set(fleet.up)
            for name in sorted(now_up - up):
                print(f"{name}: up", flush=True)
            for name in sorted(up - now_up):
                print(f"{name}: gone (its daemon stopped or the link is down)", flush=True)
            up = now_up
            for name, e in sorted(fleet.latest.items()):
                seen = True
                state = "" if name in up else "  (not alive)"
                print(f"{name:12s} {format_estimate(e)}{state}", flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        fleet.close()
    if not seen:
        print("navd watch --fleet: no vehicle heard", file=sys.stderr)
        return 1
    return 0
