"""The scorer's error components: what every accuracy figure in BENCHMARKS.md rests on."""

from __future__ import annotations

import math

from geographiclib.geodesic import Geodesic

from navd.analysis.score import _mahalanobis2, _ne_error


def test_error_components_have_the_geodesic_length_and_direction() -> None:
    g = Geodesic.WGS84
    for lat in (-84.0, -37.0, 0.0, 41.5, 70.0, 84.0):
        for lon in (-179.9999, -70.7, 0.0, 179.9999):
            for az in range(0, 360, 29):
                for d in (0.3, 7.0, 95.0, 640.0, 999.0, 5000.0):
                    r = g.Direct(lat, lon, az, d)
                    dn, de = _ne_error(r["lat2"], r["lon2"], lat, lon)
                    assert abs(math.hypot(dn, de) - d) < 2e-4, (lat, lon, az, d)
                    turn = math.remainder(math.atan2(de, dn) - math.radians(az), math.tau)
                    # the middle latitude's north against the truth's: half the meridians'
                    # convergence, terms of (d/R)^2, and the rounding of degrees
                    limit = 1.05 * d * math.tan(math.radians(abs(lat))) / (2 * 6.37e6)
                    limit += (d / 6.37e6) ** 2 + 1e-8 / d
                    assert abs(turn) < limit, (lat, az, d, turn)


def test_mahalanobis_in_closed_form_and_refusing_a_degenerate_covariance() -> None:
    assert math.isclose(_mahalanobis2(3.0, 4.0, 9.0, 16.0, 0.0), 2.0)
    # against the inverse of [[4, 1], [1, 2]] (det 7): (2*1 - 2*1*2*1 + 4*4)/7 for (1, 2)
    assert math.isclose(_mahalanobis2(1.0, 2.0, 4.0, 2.0, 1.0), (1 * 2 - 2 * 1 * 2 * 1 + 4 * 4) / 7)
    assert _mahalanobis2(1.0, 1.0, 1.0, 1.0, 1.0) == math.inf  # singular
    assert _mahalanobis2(1.0, 1.0, -1.0, -1.0, 0.0) == math.inf  # not positive definite


def test_the_ellipse_after_a_reacquisition_is_scored_on_its_own() -> None:
    """The quarter of an hour after a re-acquisition is where a fit of a few ranges stands
    in for what the filter knew: the bench reports how its ellipse holds the truth there."""
    from navd.analysis.score import REACQUIRED_S, score
    from navd.formats.truth import TruthSample
    from navd.schema import Estimate, RangeDecision

    lat0, lon0 = 37.0, -80.0
    north_m = 1.0 / 111_000.0  # a degree of latitude, about
    truth = [TruthSample(float(t), lat0, lon0, 10.0, 0.0, 1.0, 0.0, 0.0, lat0, lon0)
             for t in range(0, 3001, 10)]  # fmt: skip

    def est(t: float, err_m: float) -> Estimate:
        return Estimate(t, lat0 + err_m * north_m, lon0, 0.0, 0.0, 5.0, 5.0, 0.0, 10.0,
                        "submerged", "ok")  # fmt: skip

    # 5 m of std: 3 m off is inside the 95 % ellipse, 30 m is not; the re-acquisition at
    # 1000 s is followed by 300 s outside, then by what is inside again
    outs: list[Estimate | RangeDecision] = [
        est(float(t), 30.0 if 1000 <= t < 1300 else 3.0) for t in range(0, 3000, 10)
    ]
    outs.append(RangeDecision(1000.0, 999.0, "udb", accepted=False, reason="gate_reacquire"))
    s = score(outs, truth)
    after = REACQUIRED_S / 10
    assert s.reacquired_estimates == after
    assert math.isclose(s.reacquired_inside95, 1.0 - 30 / after)
    assert math.isclose(s.inside95, 1.0 - 30 / 300)
    # no re-acquisition: nothing to score
    none = score([o for o in outs if isinstance(o, Estimate)], truth)
    assert none.reacquired_estimates == 0 and math.isnan(none.reacquired_inside95)
    # the last submerged estimate, 3 m off in 5 m of std: what it knew of its error
    assert math.isclose(s.surfacing_d2, (3.0 / 5.0) ** 2, rel_tol=1e-3)
    assert s.surfacing_integrity == "ok"


def test_the_published_ellipse_is_set_beside_the_bounds() -> None:
    """bench-robustness reads each class's in95 against what an ellipse the size of the
    Cramer-Rao bound would score about the same estimates, and how much wider the
    published one is: an error the bound's ellipse holds is counted inside, one past it
    outside, and the stds are the RMS over the time both cover."""
    from navd.analysis.score import against_bound
    from navd.formats.truth import TruthSample
    from navd.schema import Estimate

    lat0, lon0 = 37.0, -80.0
    north_m = 1.0 / 111_000.0
    truth = [TruthSample(float(t), lat0, lon0, 10.0, 0.0, 1.0, 0.0, 0.0, lat0, lon0)
             for t in range(0, 201)]  # fmt: skip
    # the bound: 2 m per axis for the first 100 s, 4 m after; published: 10 m per axis
    ellipses = [(float(t), 4.0 if t < 100 else 16.0, 4.0 if t < 100 else 16.0, 0.0)
                for t in range(0, 201)]  # fmt: skip
    outs = [Estimate(t + 0.5, lat0 + 6.0 * north_m, lon0, 0.0, 0.0, 10.0, 10.0, 0.0, 10.0,
                     "submerged", "ok") for t in range(0, 200)]  # fmt: skip
    a = against_bound(outs, truth, ellipses)
    # 6 m north: 9 in the bound's squared distance for its first 100 s (outside the 95 %
    # ellipse, 5.99), 2.25 after (inside)
    assert math.isclose(a.inside95, 0.5, abs_tol=0.011)
    assert math.isclose(a.published_std_m, math.sqrt(200.0))
    assert math.isclose(a.bound_std_m, math.sqrt(0.5 * (8.0 + 32.0)), rel_tol=0.02)
    # nothing submerged or no bound to compare with: nothing to say
    assert math.isnan(against_bound(outs, truth, []).inside95)
    surfaced = [TruthSample(s.t, s.lat, s.lon, 0.0, 0.0, 1.0, 0.0, 0.0, lat0, lon0) for s in truth]
    assert math.isnan(against_bound(outs, surfaced, ellipses).published_std_m)
