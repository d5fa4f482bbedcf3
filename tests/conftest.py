from __future__ import annotations

import functools

from hil.scenario import load_scenario
from hil.world import Mission, simulate


@functools.cache
def mission(name: str, seed: int) -> Mission:
    """Simulated missions are deterministic; share them between tests."""
    return simulate(load_scenario(name), seed)
