"""A smoothed estimate's ellipse is an ellipse: the smoother's covariance plus what the
filter published beside its chain, taken as a covariance (navd/filter/smoothing.py)."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

from navd.analysis.replay import replay_outputs
from navd.config import load_config
from navd.filter.common import psd_part
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate
from navd.schema import Estimate


def test_what_is_added_is_the_positive_part_of_the_difference() -> None:
    rng = np.random.default_rng(7)
    for _ in range(2000):
        nn, ee, ne = (float(v) for v in rng.normal(scale=10.0, size=3))
        w, v = np.linalg.eigh(np.array([[nn, ne], [ne, ee]]))
        want = (v * np.clip(w, 0.0, None)) @ v.T
        a_nn, a_ee, a_ne = psd_part(nn, ee, ne)
        assert np.allclose([[a_nn, a_ne], [a_ne, a_ee]], want, atol=1e-9)
    assert psd_part(4.0, 1.0, 0.5) == (4.0, 1.0, 0.5)  # a covariance already: as it was
    for broken in ((math.nan, 1.0, 0.0), (math.inf, 1.0, 0.0), (1.0, 1.0, -math.inf)):
        assert psd_part(*broken) == (0.0, 0.0, 0.0)


def test_every_smoothed_ellipse_is_positive_definite() -> None:
    """cb1-small-prior refutes its current prior within a minute, and the bank publishes
    the mixture about a belief whose chain is wider than the other's in some directions:
    before, a tenth to a quarter of its smoothed ellipses had |cov_ne| > std_n std_e."""
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        write_mission(simulate(load_scenario("cb1-small-prior"), 2), d, None)
        out = replay_outputs(d / "measurements.jsonl", load_config(d / "config.yaml"), True)
    est = [o for o in out if isinstance(o, Estimate) and o.mode == "submerged"]
    assert len(est) > 1000 and all(o.smoothed for o in est)
    assert all(o.std_n * o.std_e > abs(o.cov_ne) for o in est)
