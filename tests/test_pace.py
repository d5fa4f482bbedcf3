"""The daemon's timers share the serial reader's grid (navd/daemon/pace.py), so the
process wakes once for all that is due rather than once per task."""

from __future__ import annotations

import asyncio
import math
import time

from hypothesis import given
from hypothesis import strategies as st

from navd.daemon import pace
from navd.drivers.transport import READ_WINDOW_S


@given(st.floats(0.0, 1e7), st.sampled_from([0.05, 0.1, 0.25, 1.0, 0.125]))
def test_the_next_instant_is_a_multiple_of_the_period_after_now(now: float, period: float) -> None:
    when = pace.next_multiple(now, period)
    assert when > now
    assert when - now <= period * (1 + 1e-9)
    k = when / period
    assert abs(k - round(k)) < 1e-6


def test_the_daemons_periods_fall_on_the_readers_grid() -> None:
    # the 10 Hz tick and polls, the log's flush and the health second are whole
    # numbers of read windows, so each of their instants is one the reader wakes at
    from navd.daemon.daemon import LOG_FLUSH_S

    for period in (0.1, LOG_FLUSH_S, 1.0):
        n = period / READ_WINDOW_S
        assert abs(n - round(n)) < 1e-9, period


def test_tasks_on_the_grid_wake_together() -> None:
    woke: list[tuple[float, float]] = []

    async def task(period: float) -> None:
        for _ in range(3):
            when = await pace.sleep_to_next(period, time.monotonic)
            woke.append((when, time.monotonic()))

    async def main() -> None:
        await asyncio.gather(task(0.05), task(0.1), task(0.1))

    asyncio.run(main())
    for when, now in woke:
        assert now >= when - 1e-3  # not early (the selector rounds to a millisecond)
        assert math.isclose(when / 0.05, round(when / 0.05), abs_tol=1e-6)
    # the 0.1 s tasks woke at instants the 0.05 s task also had
    grid = {round(w / 0.05) for w, _ in woke}
    assert len(grid) < len(woke)
