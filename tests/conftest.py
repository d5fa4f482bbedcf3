from __future__ import annotations

import functools
import os

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
