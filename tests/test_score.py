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
