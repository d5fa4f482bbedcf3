"""What a wake-up of an asyncio daemon costs on this machine, with nothing of navd in it.

``python -m bench.loop_wakeups`` runs a bare event loop for ``--seconds`` in each of
three shapes and prints its CPU as a share of one core:

* a read timer every 20 ms doing one ``poll`` of a pipe, beside five tasks sleeping at
  10, 10, 10, 10 and 4 Hz on phases of their own (navd's timers before
  navd/daemon/pace.py);
* the same with the tasks sleeping to multiples of their periods;
* a read timer every 50 ms and the tasks on its grid (navd's timers now).

The difference between the shapes is the price of the wake-ups alone.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import select
import sys
import time

from navd.daemon import pace

_TASK_HZ = (10.0, 10.0, 10.0, 10.0, 4.0)


async def _task(hz: float, aligned: bool) -> None:
    period = 1.0 / hz
    nxt = time.monotonic()
    while True:
        if aligned:
            await pace.sleep_to_next(period, time.monotonic)
        else:
            nxt += period
            await asyncio.sleep(max(0.0, nxt - time.monotonic()))


async def _loop(window: float, aligned: bool, seconds: float) -> float:
    loop = asyncio.get_running_loop()
    r, w = os.pipe()
    poller = select.poll()
    poller.register(r, select.POLLIN)

    def read() -> None:
        poller.poll(0)
        loop.call_at(pace.next_multiple(loop.time(), window), read)

    read()
    tasks = [asyncio.create_task(_task(hz, aligned)) for hz in _TASK_HZ]
    c0, t0 = time.process_time(), time.monotonic()
    await asyncio.sleep(seconds)
    share = 100.0 * (time.process_time() - c0) / (time.monotonic() - t0)
    for t in tasks:
        t.cancel()
    os.close(r)
    os.close(w)
    return share


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=30.0)
    args = p.parse_args()
    shapes = (
        ("20 ms read timer, tasks on their own phases", 0.02, False),
        ("20 ms read timer, tasks on the grid", 0.02, True),
        ("50 ms read timer, tasks on its grid", 0.05, True),
    )
    print(f"`python -m bench.loop_wakeups --seconds {args.seconds:g}`\n")
    print("| loop | % of one core |\n|---|---|")
    for name, window, aligned in shapes:
        share = asyncio.run(_loop(window, aligned, args.seconds))
        print(f"| {name} | {share:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
