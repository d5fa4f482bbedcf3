from __future__ import annotations

import functools
import os

import numpy as np
from hypothesis import settings

from navd.hil.scenario import load_scenario
from navd.hil.world import Mission, simulate

# `make test` (and so CI) must give the same verdict on every run: the property tests
# draw a fixed sequence of examples there.  `make fuzz` draws new ones on every run; a
# failure it finds becomes a plain regression test (see test_codecs.py, Castle).
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("NAVD_HYPOTHESIS", "repeatable"))


@functools.cache
def mission(name: str, seed: int) -> Mission:
    """Simulated missions are deterministic; share them between tests."""
    return simulate(load_scenario(name), seed)


def current_walk(dt: float, q2: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and current (north, east, current north, current east) over ``dt``: the
    transition, and the noise of a current walking at ``q2`` (m/s)^2/s, integrated."""
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    Q = np.zeros((4, 4))
    for i in (0, 1):
        Q[i, i] = q2 * dt**3 / 3.0
        Q[i, i + 2] = Q[i + 2, i] = q2 * dt**2 / 2.0
        Q[i + 2, i + 2] = q2 * dt
    return F, Q


class DeviceHost:
    """What a device task needs of the daemon (navd/daemon/devices/base.py, ``Host``): its
    vitals, a clock, where records go, and no log (the decoder as it is)."""

    def __init__(self) -> None:
        from navd.daemon.health import Vitals

        self.vitals = Vitals(rate_hz=10.0, ping_interval_s=10.0, stale_s=1.0)
        self.fed: list[object] = []

    def clock(self) -> float:
        import time

        return time.monotonic()

    def feed(self, rec: object) -> None:
        self.fed.append(rec)

    def logged(self, name: str, decoder: object) -> object:
        return decoder
