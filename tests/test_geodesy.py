"""navd.geodesy against GeographicLib (geodesics) and PROJ (ECEF)."""

from __future__ import annotations

import math

import pytest
from geographiclib.geodesic import Geodesic
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Transformer

from navd import geodesy

G = Geodesic.WGS84
TO_ECEF = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
R = math.radians

PLACES = [
    (37.0482, -80.6679),  # Claytor Lake
    (38.3230, -76.3963),  # Chesapeake Bay
    (-42.93, 147.36),  # southern hemisphere
    (80.0, 15.0),
    (-80.0, -60.0),
    (-16.8, 179.995),  # next to the antimeridian
    (0.0, 0.0),
]


@pytest.mark.parametrize("lat,lon", PLACES)
@pytest.mark.parametrize("azi", [0.0, 37.0, 90.0, 135.0, 210.0, 299.0])
def test_destination_agrees_with_geographiclib_over_10km(
    lat: float, lon: float, azi: float
) -> None:
    ref = G.Direct(lat, lon, azi, 10_000.0)
    la, lo, az2 = geodesy.destination(R(lat), R(lon), R(azi), 10_000.0)
    miss = G.Inverse(ref["lat2"], ref["lon2"], math.degrees(la), math.degrees(lo))["s12"]
    assert miss < 1e-3
    assert abs(math.degrees(geodesy.wrap_lon(az2 - R(ref["azi2"])))) < 1e-6


def test_destination_crosses_the_antimeridian() -> None:
    la, lo, _ = geodesy.destination(R(-16.8), R(179.995), R(90.0), 2000.0)
    assert -180.0 < math.degrees(lo) < -179.9
    ref = G.Direct(-16.8, 179.995, 90.0, 2000.0)
    assert G.Inverse(ref["lat2"], ref["lon2"], math.degrees(la), math.degrees(lo))["s12"] < 1e-3


@pytest.mark.parametrize("lat,lon", PLACES)
@pytest.mark.parametrize("hd", [-500.0, -1.5, 0.0, 120.0])
def test_ecef_agrees_with_proj(lat: float, lon: float, hd: float) -> None:
    ref = TO_ECEF.transform(lon, lat, hd)
    got = geodesy.geodetic_to_ecef(R(lat), R(lon), hd)
    assert math.dist(ref, got) < 1e-3


def test_depth_enters_as_negative_height() -> None:
    """Eq. 3.3: the vehicle at depth d is at height h - d."""
    a = geodesy.geodetic_to_ecef(R(37.0), R(-80.0), 530.0, 3.0)
    b = geodesy.geodetic_to_ecef(R(37.0), R(-80.0), 527.0, 0.0)
    assert math.dist(a, b) < 1e-9


@given(lat=st.floats(-89.0, 89.0), lon=st.floats(-180.0, 179.999), hd=st.floats(-5000.0, 5000.0))
@settings(max_examples=200, deadline=None)
def test_ecef_round_trip(lat: float, lon: float, hd: float) -> None:
    x, y, z = geodesy.geodetic_to_ecef(R(lat), R(lon), hd)
    la, lo, h = geodesy.ecef_to_geodetic(x, y, z)
    back = geodesy.geodetic_to_ecef(la, lo, h)
    assert math.dist((x, y, z), back) < 1e-6
    assert abs(h - hd) < 1e-6


def _eq_3_12(lat1, lon1, hd1, lat2, lon2, hd2):
    """Eq. 3.12 written out literally, to check the ECEF-difference evaluation."""
    e2 = geodesy.WGS84.e2
    n1, n2 = geodesy.prime_vertical_radius(lat1), geodesy.prime_vertical_radius(lat2)
    mu1, mu2 = n1 + hd1, n2 + hd2
    rho1, rho2 = (1 - e2) * n1 + hd1, (1 - e2) * n2 + hd2
    return math.sqrt(
        mu1**2 * math.cos(lat1) ** 2
        + mu2**2 * math.cos(lat2) ** 2
        - 2 * mu1 * mu2 * math.cos(lat1) * math.cos(lat2) * math.cos(lon1 - lon2)
        + (rho1 * math.sin(lat1) - rho2 * math.sin(lat2)) ** 2
    )


@pytest.mark.parametrize("lat,lon", PLACES)
def test_ecef_distance_is_eq_3_12(lat: float, lon: float) -> None:
    p2 = G.Direct(lat, lon, 63.0, 800.0)
    args = (R(lat), R(lon), 530.0 - 1.0, R(p2["lat2"]), R(p2["lon2"]), 530.0 - 3.0)
    assert geodesy.ecef_distance(*args) == pytest.approx(_eq_3_12(*args), abs=1e-4)


def test_great_circle_step_is_eq_2_5_on_a_sphere() -> None:
    radius = 6_371_000.0
    sphere = Geodesic(radius, 0.0)
    for lat, lon in PLACES:
        for azi in (0.0, 45.0, 200.0):
            la, lo = geodesy.great_circle_step(R(lat), R(lon), R(azi), 5000.0, radius)
            ref = sphere.Direct(lat, lon, azi, 5000.0)
            miss = sphere.Inverse(ref["lat2"], ref["lon2"], math.degrees(la), math.degrees(lo))
            assert miss["s12"] < 1e-6


def test_centre_distance_is_eq_3_9() -> None:
    lat, lon, hd = R(37.05), R(-80.66), 527.0
    x, y, z = geodesy.geodetic_to_ecef(lat, lon, hd)
    assert geodesy.centre_distance(lat, lon, hd) == pytest.approx(math.sqrt(x * x + y * y + z * z))


@pytest.mark.parametrize("lat", [0.0, 37.0, -42.9, 60.0, 78.2])
def test_metres_per_degree_matches_the_ellipsoid(lat: float) -> None:
    m_lat, m_lon = geodesy.metres_per_degree(R(lat))
    ref_lat = G.Inverse(lat - 0.5, 0.0, lat + 0.5, 0.0)["s12"]
    ref_lon = G.Inverse(lat, 0.0, lat, 1.0)["s12"]
    assert m_lat == pytest.approx(ref_lat, abs=1.0)  # eq. 3.15 is a truncated series
    assert m_lon == pytest.approx(ref_lon, abs=1.0)


def test_range_gradient_matches_finite_differences() -> None:
    lat, lon, hd = R(38.32), R(-76.39), -1.5
    tgt = (R(38.3212), R(-76.3921), -1.0)
    r, dn, de = geodesy.range_and_gradient(lat, lon, hd, *tgt)
    h = 0.01

    def at(dn_m: float, de_m: float) -> float:
        la, lo = geodesy.offset_position(lat, lon, dn_m, de_m, hd)
        return geodesy.ecef_distance(la, lo, hd, *tgt)

    assert r == pytest.approx(at(0.0, 0.0))
    assert dn == pytest.approx((at(h, 0.0) - at(-h, 0.0)) / (2 * h), abs=1e-6)
    assert de == pytest.approx((at(0.0, h) - at(0.0, -h)) / (2 * h), abs=1e-6)


def test_enu_offset_and_offset_position_invert_each_other() -> None:
    lat, lon = R(-16.8), R(179.999)
    la, lo = geodesy.offset_position(lat, lon, 120.0, 340.0)
    e, n, _ = geodesy.enu_offset(lat, lon, 0.0, la, lo, 0.0)
    assert e == pytest.approx(340.0, abs=0.05)
    assert n == pytest.approx(120.0, abs=0.05)


@pytest.mark.parametrize("lat,lon", PLACES)
def test_nearby_offset_is_the_geodesic_up_to_2km(lat: float, lon: float) -> None:
    for azi in range(0, 360, 30):
        for s in (1.0, 100.0, 2000.0):
            g = G.Direct(lat, lon, azi, s)
            n, e = geodesy.nearby_offset(R(lat), R(lon), R(g["lat2"]), R(g["lon2"]))
            assert math.hypot(n, e) == pytest.approx(s, abs=1e-3)


@given(st.floats(-1e4, 1e4))
def test_wrap_lon_range(lon: float) -> None:
    w = geodesy.wrap_lon(lon)
    assert -math.pi <= w < math.pi
    assert math.isclose(math.sin(w), math.sin(lon), abs_tol=1e-9)
