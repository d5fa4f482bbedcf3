"""Many independent missions at once: on this machine's cores, or on a Dask cluster.

Each job is a pure function of its arguments (a mission's seed, a log's path), so the
results are the same whatever the number of workers, and come back in the order asked.
The local pool keeps its worker processes for the whole run: a worker imports navd and
numpy once, not once per mission.  For work beyond one machine, ``scheduler`` names a
running ``dask scheduler`` (``tcp://host:8786``); its workers need navd installed, the
same version, and the files the jobs name.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

R = TypeVar("R")


def default_jobs() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def run_all(
    fn: Callable[..., R],
    *arg_lists: Sequence[object],
    jobs: int | None = None,
    scheduler: str | None = None,
) -> list[R]:
    """``[fn(*args) for args in zip(*arg_lists)]``, spread over ``jobs`` processes or a cluster."""
    calls = list(zip(*arg_lists, strict=True))
    if not calls:
        return []
    if scheduler:
        return _on_dask(fn, calls, len(arg_lists), scheduler)
    n = jobs or default_jobs()
    if n == 1 or len(calls) <= 1:
        return [fn(*a) for a in calls]
    with ProcessPoolExecutor(min(n, len(calls))) as pool:
        # chunks of one: missions differ tenfold in length, so no worker waits on a batch
        return list(pool.map(fn, *_columns(calls, len(arg_lists))))


def _columns(calls: list[tuple[object, ...]], n: int) -> list[Iterable[object]]:
    return [[c[i] for c in calls] for i in range(n)]


def _on_dask(
    fn: Callable[..., R], calls: list[tuple[object, ...]], n_args: int, scheduler: str
) -> list[R]:
    try:
        from distributed import Client
    except ImportError:
        raise SystemExit(
            "navd: --scheduler needs Dask distributed: pip install 'navd[cluster]'"
        ) from None
    with Client(scheduler, set_as_default=False) as client:
        # pure=False: two calls with equal arguments are still two missions to run
        futures = client.map(fn, *_columns(calls, n_args), pure=False)
        return list(client.gather(futures))
