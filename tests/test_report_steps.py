"""The report's steps apart from its figures (what the summary says, without matplotlib),
and navd watch's line for an estimate."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

from navd.analysis.report import ReportInput, errors_against_truth, minutes_axis, summary
from navd.formats.truth import TruthSample
from navd.schema import Estimate, RangeDecision


def _est(t: float, mode: str = "submerged", **kw: object) -> Estimate:
    lat = 37.0 + 1e-5 * t
    return Estimate(t, lat, -80.6, 0.1, 0.0, 3.0, 3.0, 0.0, 2.0, mode, "ok", **kw)  # type: ignore[arg-type]


def _mission() -> ReportInput:
    est = [_est(0.0, "surface", t_utc="2026-06-01T12:00:00.000+00:00"), _est(60.0), _est(120.0)]
    dec = [
        RangeDecision(60.0, 59.0, "udb", accepted=True, reason="ok", range_m=500.0),
        RangeDecision(90.0, 89.0, "udb", reason="gate", range_m=900.0),
        RangeDecision(100.0, 99.0, "udb", reason="no_beacon_position"),
    ]
    truth = [
        TruthSample(t, 37.0, -80.6, 2.0, 0.0, 1.0, 0.0, 0.0, 37.0, -80.6)
        for t in (0.0, 60.0, 120.0)
    ]
    return ReportInput(est, dec, [], truth, "truth.jsonl")


def test_the_summary_counts_what_the_filter_did() -> None:
    lines = summary(_mission())
    assert lines[0] == "estimates: 3 over 120 s"
    assert lines[1] == "ranges: 3 reached the filter, 1 accepted, 2 rejected"
    assert lines[2] == "rejected by reason: gate 1, no_beacon_position 1"
    assert any(x.startswith("against the truth, submerged: RMS") for x in lines)
    assert lines[-1].startswith("final estimate: 37.0012000, -80.6000000")


def test_the_summary_says_how_long_the_estimate_was_ok_and_why_not() -> None:
    """Over the submerged estimates only, with a reason's numbers taken out so that one
    reason with different figures counts once."""
    states = [
        ("ok", None), ("ok", None), ("ok", None), ("ok", None),
        ("degraded", "position std 31 m over 25 m"), ("degraded", "position std 40 m over 25 m"),
        ("degraded", "one range placed the estimate, and none has checked it yet"),
        ("lost", "8 ranges or fixes refused in a row"),
    ]  # fmt: skip
    est = [_est(0.0, "surface"), _est(1.0, "surface")]
    for k, (state, why) in enumerate(states):
        est.append(replace(_est(10.0 + k), integrity=state, integrity_reason=why))
    line = next(x for x in summary(ReportInput(est, [], [], [], "")) if "integrity" in x)
    assert line == (
        "integrity while submerged: ok 50%, degraded 38%, lost 12%; not ok for: "
        "position std # m over # m 25%, "
        "one range placed the estimate, and none has checked it yet 12%, "
        "# ranges or fixes refused in a row 12%"
    )


def test_the_summary_says_when_the_calibration_priors_were_refuted() -> None:
    m = _mission()
    assert not any("refuted" in x for x in summary(m))
    refuted = _est(120.0, calibration_refuted=True, heading_bias_deg=4.5, speed_scale=0.95)
    m.estimates[2:] = [refuted]
    line = next(x for x in summary(m) if "refuted" in x)
    assert line.startswith("calibration priors refuted at 120 s")
    assert "heading bias +4.5 deg, speed scale 0.950" in line


def test_time_is_minutes_since_the_first_estimates_utc() -> None:
    minutes, label = minutes_axis(_mission().estimates)
    assert minutes(120.0) == 2.0 and label == "minutes since 2026-06-01T12:00:00.000+00:00"


def test_the_error_against_the_truth_is_in_metres() -> None:
    err = errors_against_truth(_mission())
    # 1e-5 degree of latitude a second: about 66.7 m after a minute
    assert [round(e) for _, e in err] == [0, 67, 133]


def test_the_summary_needs_no_matplotlib() -> None:
    code = (
        "import sys; sys.modules['matplotlib'] = None; "
        "from tests.test_report_steps import _mission; "
        "from navd.analysis.report import summary; print(len(summary(_mission())))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert int(r.stdout) >= 5


def test_navd_watch_marks_an_estimate_whose_calibration_priors_were_refuted() -> None:
    from navd.watch import format_estimate

    assert "refuted" not in format_estimate(_est(60.0))
    assert format_estimate(_est(60.0, calibration_refuted=True)).endswith(
        "ok  calibration priors refuted"
    )


def _ranges_with_nis(values: list[float | None], moving: bool = False) -> ReportInput:
    m = _mission()
    dec = [
        RangeDecision(
            60.0 + i, 59.0 + i, "t1", beacon_lat=37.01 + (1e-5 * i if moving else 0.0),
            beacon_lon=-80.6, accepted=True, reason="ok", nis=v,
        )  # fmt: skip
        for i, v in enumerate(values)
    ]
    return ReportInput(m.estimates, dec, [], [], "")


def _nis_line(values: list[float | None], moving: bool = False) -> str | None:
    return next((x for x in summary(_ranges_with_nis(values, moving)) if "NIS" in x), None)


def test_the_summary_says_which_way_a_fixed_transponders_ranges_find_the_noise_model() -> None:
    """The accepted ranges' mean NIS is the one test of the ellipse a mission without truth
    allows: well below what a right model gives, the ellipse is wider than the error;
    well above, narrower."""
    wide = _nis_line([0.1] * 40)
    assert wide is not None
    assert wide.startswith("ranges against the noise model: mean NIS 0.10 over 40")
    assert "wider than the error" in wide
    fits = _nis_line([0.5, 1.3] * 20)
    assert fits is not None and fits.endswith("(about 0.9 when it fits)")
    narrow = _nis_line([3.0] * 40)
    assert narrow is not None and "narrower than the error" in narrow
    # too few to judge by, and ranges without a gate's variance are not counted
    assert _nis_line([0.1] * 29 + [None] * 20) is None


def test_a_moving_beacons_ranges_give_no_verdict_on_the_ellipse() -> None:
    """A boat's GPS wander outweighs the filter's share of its ranges' variance: Monte
    Carlo missions whose ellipse was too narrow averaged NIS well below 1 there
    (BENCHMARKS.md, "The ranges' test of the noise model")."""
    line = _nis_line([0.1] * 40, moving=True)
    assert line is not None and "no verdict on the ellipse" in line
    assert "wider" not in line and "narrower" not in line
