"""DVL dead reckoning and its error prediction (seed 002)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import mission
from serialised import rows

from navd.analysis.replay import run_navigator
from navd.analysis.score import _ne_error
from navd.filter.dvl import DvlDeadReckoner, DvlSpec, rotation_body_to_ned, velocity_error
from navd.formats.mlog import MeasurementLog
from navd.hil.sim_cli import mission_config
from navd.settings import config_from_dict


@pytest.mark.parametrize("att", [(0.0, 0.0, 0.3), (0.1, -0.2, 2.5), (-0.3, 0.25, -1.2)])
def test_eq_14_is_the_first_order_error_of_the_rotation(att) -> None:
    v = np.array([1.4, 0.2, -0.1])
    dv = np.array([0.01, -0.02, 0.005])
    da = np.array([0.002, -0.001, 0.003])
    exact = (
        np.array(rotation_body_to_ned(*(np.array(att) + da))) @ (v + dv)
        - np.array(rotation_body_to_ned(*att)) @ v
    )
    first = velocity_error(tuple(v), att, tuple(dv), tuple(da))
    np.testing.assert_allclose(first, exact, atol=2e-4)


def test_rotation_is_orthonormal() -> None:
    R = np.array(rotation_body_to_ned(0.2, -0.4, 1.9))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)


def test_spike_is_replaced_but_a_real_change_is_believed() -> None:
    d = DvlDeadReckoner(DvlSpec(max_rejections=3), 0.0)
    d.reset(0.7, -1.2, 0.0)
    assert d.velocity(0.1, 1.0, 0.0, 0.0)
    assert not d.velocity(0.2, 3.5, 0.0, 0.0)  # a spike
    assert d.v == (1.0, 0.0, 0.0)
    assert d.velocity(0.3, 1.0, 0.0, 0.0)
    # a step the filter does not believe at first, then does
    oks = [d.velocity(0.4 + 0.1 * k, 2.0, 0.0, 0.0) for k in range(5)]
    assert oks[:3] == [False] * 3 and oks[3]
    assert d.v == (2.0, 0.0, 0.0)


def test_predicted_error_bounds_the_actual_and_tells_when_to_surface() -> None:
    m = mission("dvl", 1)
    cfg = config_from_dict(mission_config(m))
    res = run_navigator(MeasurementLog({}, m.records, []), cfg)
    truth = {round(s.t, 3): s for s in m.truth}
    sub = [o for o in rows(res.outputs) if o["type"] == "estimate" and o["mode"] == "submerged"]
    last = sub[-1]
    tr = truth[round(last["t"], 3)]
    dvl_err = math.hypot(*_ne_error(last["dvl_lat"], last["dvl_lon"], tr.lat, tr.lon))
    rpm_err = math.hypot(*_ne_error(last["dr_lat"], last["dr_lon"], tr.lat, tr.lon))
    assert dvl_err < rpm_err / 2  # the DVL knows the current; the RPM cannot
    assert dvl_err < last["dvl_error_pred_m"]  # the specification errors bound the real ones
    assert res.counters["dvl_spikes"] > 0
    # the time to the limit falls as the predicted error grows, and reaches zero
    ttl = [o["dvl_time_to_limit_s"] for o in sub]
    assert ttl[0] > ttl[len(ttl) // 2] >= ttl[-1] == 0.0
