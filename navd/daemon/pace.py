"""The daemon's periodic work on one grid of the event loop's clock.

Waking the process costs more than most of what a wake-up then does: a bare asyncio
loop with a 50 Hz read timer and five tasks sleeping at 10 and 4 Hz, each on its own
phase, took 0.85 % of a core on the bench machine, and 0.45 % with a 50 ms read timer
and the tasks on its grid (``python -m bench.loop_wakeups``; BENCHMARKS.md, "Daemon").
So every periodic task sleeps to the next multiple of its period, as the serial reader
(navd/drivers/transport.py) and the filter's ticker do: a poll at 10 Hz, the modem's
keeper, the log's flush and the health once a second all fall on instants the reader
wakes at anyway, and the process wakes once for all that is due.  A task that falls
behind skips to the next multiple instead of catching up in a burst.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable


def next_multiple(now: float, period: float) -> float:
    """The first multiple of ``period`` after ``now``."""
    return (math.floor(now / period) + 1.0) * period


async def sleep_to_next(period: float, clock: Callable[[], float]) -> float:
    """Sleep to the next multiple of ``period`` on ``clock``, and return it."""
    when = next_multiple(clock(), period)
    await asyncio.sleep(max(0.0, when - clock()))
    return when
