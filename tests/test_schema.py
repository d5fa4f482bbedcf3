"""One output schema: what the filter writes is what a reader gets back, under one name."""

from __future__ import annotations

import dataclasses

import pytest

from navd.formats import jsonlines
from navd.schema import Estimate, RangeDecision, finite, from_dict, output_of, to_dict


def _estimate(**kw: object) -> Estimate:
    base = dict(t=1.0, lat=37.0, lon=-80.0, current_n=0.1, current_e=0.0, std_n=3.0)
    base |= dict(std_e=3.0, cov_ne=0.0, depth=2.0, mode="submerged", integrity="ok")
    base |= kw
    return Estimate(**base)  # type: ignore[arg-type]


def test_optional_fields_are_left_out_and_type_comes_first() -> None:
    d = to_dict(_estimate())
    assert next(iter(d)) == "type" and d["type"] == "estimate"
    assert "dr_lat" not in d and "integrity_reason" not in d
    d = to_dict(_estimate(dr_lat=37.1, dr_lon=-80.1))
    assert d["dr_lat"] == 37.1


def test_a_reader_ignores_fields_it_does_not_know() -> None:
    """Fields are only ever added: an older autopilot keeps working."""
    d = to_dict(_estimate()) | {"schema": 1, "seq": 7, "a_field_from_the_future": 1}
    assert from_dict(Estimate, d) == _estimate()


def test_a_range_refused_before_the_gate_has_null_residual() -> None:
    d = to_dict(RangeDecision(5.0, 4.0, "udb", reason="not_initialised"))
    assert d["accepted"] is False and d["residual_m"] is None and d["gate_m"] is None
    assert "range_m" not in d


def test_decisions_are_found_in_replay_output_and_daemon_log_alike() -> None:
    dec = to_dict(RangeDecision(5.0, 4.0, "udb", accepted=True, reason="ok"))
    measured = {"type": "range", "t": 5.0, "t_ping": 4.0, "m": 700.0, "beacon": "udb"}
    est = to_dict(_estimate())
    for rows in ([est, dec], [est, measured, {**dec, "type": "decision"}]):
        got = [o for o in map(output_of, rows) if o is not None]
        assert got == [_estimate(), RangeDecision(5.0, 4.0, "udb", accepted=True, reason="ok")]


@pytest.mark.parametrize(
    "row, says",
    [
        ({"lat": None}, "an estimate without lat"),
        ({"std_n": "3"}, "an estimate whose std_n is not a number"),
        ({"depth": True}, "an estimate whose depth is not a number"),
    ],
)
def test_a_row_that_is_not_an_estimate_is_named(row: dict, says: str) -> None:
    assert output_of(to_dict(_estimate()) | row) == says
    bare = {k: v for k, v in to_dict(_estimate()).items() if k != "mode"}
    assert output_of(bare) == "an estimate without mode"


def test_outputs_are_frozen_and_a_nan_is_seen() -> None:
    e = _estimate()
    with pytest.raises(dataclasses.FrozenInstanceError):
        e.lat = 0.0  # type: ignore[misc]
    assert finite(e) and finite(_estimate(dr_lat=None))
    assert not finite(_estimate(dr_lat=float("nan"))) and not finite(_estimate(std_n=float("inf")))


def test_the_client_ignores_what_is_not_navds_schema() -> None:
    from navd.client import _typed

    class Payload:
        def __init__(self, b: bytes) -> None:
            self.b = b

        def to_bytes(self) -> bytes:
            return self.b

    assert _typed(Estimate, Payload(b'{"t": 1}')) is None  # required fields missing
    assert _typed(Estimate, Payload(b"not json")) is None
    assert _typed(Estimate, Payload(b"[1, 2]")) is None
    good = Payload(jsonlines.dumps(to_dict(_estimate())))
    assert _typed(Estimate, good) == _estimate()
