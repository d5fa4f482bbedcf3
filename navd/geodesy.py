"""Ellipsoid arithmetic: the one place in navd that knows the shape of the Earth.

Angles are radians and lengths metres everywhere in this module; degrees only
appear at the edges (records and output).  Equation numbers refer to Jabari 2016,
*Range-Based AUV Navigation Expressed in Geodetic Coordinates* (seed 000).

Two ways to move a point are provided, on purpose:

* :func:`great_circle_step` is the thesis' step, eq. 2.5 on a sphere whose radius
  is the point's distance from the Earth's centre (eq. 3.9).  It is what the
  ``thesis`` filter mode uses and it is only good for short steps: over 10 km it
  is tens of metres off the ellipsoid.
* :func:`destination` integrates the geodesic equations on the ellipsoid with
  fourth-order Runge-Kutta (the differential form used by Karney, *Algorithms for
  geodesics*, J. Geodesy 2013, eq. 1 and Clairaut's relation).  It agrees with
  GeographicLib's direct solution to well under a millimetre over 10 km and is
  what everything else uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "Ellipsoid",
    "WGS84",
    "prime_vertical_radius",
    "meridian_radius",
    "geodetic_to_ecef",
    "ecef_to_geodetic",
    "ecef_distance",
    "centre_distance",
    "great_circle_step",
    "destination",
    "metres_per_degree",
    "wrap_lon",
    "enu_offset",
    "offset_position",
    "range_and_gradient",
]


@dataclass(frozen=True, slots=True)
class Ellipsoid:
    """A reference ellipsoid given by its semi-major axis ``a`` and flattening ``f``."""

    a: float
    f: float

    @property
    def e2(self) -> float:
        """First eccentricity squared, e^2 = f (2 - f)."""
        return self.f * (2.0 - self.f)

    @property
    def b(self) -> float:
        """Semi-minor axis."""
        return self.a * (1.0 - self.f)


#: WGS-84 (NIMA TR8350.2; seed 000 Table 2.1).
WGS84 = Ellipsoid(a=6378137.0, f=1.0 / 298.257223563)

# Maximum length of one Runge-Kutta substep in :func:`destination`.  The local
# truncation error scales as (step / R)^5 R: 5 km gives ~1e-7 m.
_RK_STEP_M = 5000.0
# Once round the Earth in RK steps: a longer path can only come from a corrupt input,
# and walking it must still take bounded time (1e300 m would never finish).
_RK_MAX_STEPS = 8100
# Shorter moves (every filter step) take one midpoint step instead of RK4.
MIDPOINT_MAX_M = 50.0


def prime_vertical_radius(lat: float, ell: Ellipsoid = WGS84) -> float:
    """N(phi), radius of curvature in the prime vertical (eq. 2.2)."""
    s = math.sin(lat)
    return ell.a / math.sqrt(1.0 - ell.e2 * s * s)


def meridian_radius(lat: float, ell: Ellipsoid = WGS84) -> float:
    """M(phi), radius of curvature in the meridian."""
    s = math.sin(lat)
    w2 = 1.0 - ell.e2 * s * s
    return ell.a * (1.0 - ell.e2) / (w2 * math.sqrt(w2))


def geodetic_to_ecef(
    lat: float, lon: float, h: float = 0.0, depth: float = 0.0, ell: Ellipsoid = WGS84
) -> tuple[float, float, float]:
    """ECEF coordinates of a point at ellipsoidal height ``h`` and ``depth`` below it (eq. 3.3)."""
    n = prime_vertical_radius(lat, ell)
    hd = h - depth
    cl = math.cos(lat)
    return (
        (n + hd) * cl * math.cos(lon),
        (n + hd) * cl * math.sin(lon),
        ((1.0 - ell.e2) * n + hd) * math.sin(lat),
    )


def ecef_to_geodetic(
    x: float, y: float, z: float, ell: Ellipsoid = WGS84
) -> tuple[float, float, float]:
    """Geodetic latitude, longitude and height of an ECEF point.

    Bowring's iteration on the parametric latitude; three iterations reach
    sub-micrometre accuracy for points near the surface, and a fourth is cheap margin.
    """
    e2 = ell.e2
    b = ell.b
    ep2 = e2 / (1.0 - e2)
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    beta = math.atan2(z, p * (1.0 - ell.f))
    lat = 0.0
    for _ in range(4):
        sb, cb = math.sin(beta), math.cos(beta)
        lat = math.atan2(z + ep2 * b * sb**3, p - e2 * ell.a * cb**3)
        beta = math.atan2((1.0 - ell.f) * math.sin(lat), math.cos(lat))
    n = prime_vertical_radius(lat, ell)
    cl, sl = math.cos(lat), math.sin(lat)
    # Height along the normal, well conditioned away from both poles and equator.
    h = p * cl + z * sl - ell.a * ell.a / n
    return lat, lon, h


def ecef_distance(
    lat1: float,
    lon1: float,
    hd1: float,
    lat2: float,
    lon2: float,
    hd2: float,
    ell: Ellipsoid = WGS84,
) -> float:
    """Straight-line distance between two points given as (lat, lon, h - depth) (eq. 3.12).

    Eq. 3.12 is the norm of the ECEF difference written out; it is evaluated here as
    that difference, which is the same quantity without the cancellation between
    terms of order R^2 that the expanded form suffers for short ranges.
    """
    x1, y1, z1 = geodetic_to_ecef(lat1, lon1, hd1, 0.0, ell)
    x2, y2, z2 = geodetic_to_ecef(lat2, lon2, hd2, 0.0, ell)
    return math.sqrt((x1 - x2) ** 2 + (y1 - y2) ** 2 + (z1 - z2) ** 2)


def centre_distance(lat: float, lon: float, hd: float = 0.0, ell: Ellipsoid = WGS84) -> float:
    """Distance of a point from the Earth's centre, the per-step sphere radius (eq. 3.8, 3.9)."""
    x, y, z = geodetic_to_ecef(lat, lon, hd, 0.0, ell)
    return math.sqrt(x * x + y * y + z * z)


def great_circle_step(
    lat: float, lon: float, heading: float, distance: float, radius: float
) -> tuple[float, float]:
    """Destination along a great circle of a sphere of ``radius`` (eq. 2.5, Appendix A)."""
    xi = distance / radius
    sl, cl = math.sin(lat), math.cos(lat)
    sx, cx = math.sin(xi), math.cos(xi)
    lat2 = math.asin(max(-1.0, min(1.0, cx * sl + cl * math.cos(heading) * sx)))
    lon2 = lon + math.atan2(math.sin(heading) * sx * cl, cx - sl * math.sin(lat2))
    return lat2, wrap_lon(lon2)


def _geodesic_rates(
    lat: float, az: float, hd: float, a: float, e2: float
) -> tuple[float, float, float]:
    # d(lat)/ds, d(lon)/ds, d(azimuth)/ds along a geodesic; Clairaut's relation
    # N cos(lat) sin(az) = const gives the azimuth rate.
    s = math.sin(lat)
    w2 = 1.0 - e2 * s * s
    n = a / math.sqrt(w2) + hd
    m = a * (1.0 - e2) / (w2 * math.sqrt(w2)) + hd
    sa, ca = math.sin(az), math.cos(az)
    cl = math.cos(lat)
    return ca / m, sa / (n * cl), sa * s / (n * cl)


def destination(
    lat: float,
    lon: float,
    azimuth: float,
    distance: float,
    hd: float = 0.0,
    ell: Ellipsoid = WGS84,
) -> tuple[float, float, float]:
    """Point reached after ``distance`` metres along the geodesic leaving at ``azimuth``.

    ``hd`` is the height of the path above the ellipsoid (negative below it); the
    radii of curvature are scaled to that height.  Returns (lat, lon, forward azimuth).
    Valid at any latitude short of the poles and across the antimeridian.
    """
    if distance == 0.0:
        return lat, lon, azimuth
    a, e2 = ell.a, ell.e2
    if abs(distance) <= MIDPOINT_MAX_M:
        # the filter's 10 Hz steps: the midpoint rule's error, ~(d/R)^3 R, is below 1e-12 m
        k1 = _geodesic_rates(lat, azimuth, hd, a, e2)
        h2 = 0.5 * distance
        k2 = _geodesic_rates(lat + h2 * k1[0], azimuth + h2 * k1[2], hd, a, e2)
        return (
            lat + distance * k2[0],
            wrap_lon(lon + distance * k2[1]),
            azimuth + distance * k2[2],
        )
    if not math.isfinite(distance):
        return math.nan, math.nan, math.nan
    steps = min(_RK_MAX_STEPS, max(1, math.ceil(abs(distance) / _RK_STEP_M)))
    h = distance / steps
    la, lo, az = lat, lon, azimuth
    for _ in range(steps):
        k1 = _geodesic_rates(la, az, hd, a, e2)
        k2 = _geodesic_rates(la + 0.5 * h * k1[0], az + 0.5 * h * k1[2], hd, a, e2)
        k3 = _geodesic_rates(la + 0.5 * h * k2[0], az + 0.5 * h * k2[2], hd, a, e2)
        k4 = _geodesic_rates(la + h * k3[0], az + h * k3[2], hd, a, e2)
        la += h * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]) / 6.0
        lo += h * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]) / 6.0
        az += h * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]) / 6.0
    return la, wrap_lon(lo), az


def offset_position(
    lat: float, lon: float, d_north: float, d_east: float, hd: float = 0.0, ell: Ellipsoid = WGS84
) -> tuple[float, float]:
    """Move a point by a local north/east offset in metres (along the geodesic)."""
    dist = math.hypot(d_north, d_east)
    if dist == 0.0:
        return lat, lon
    la, lo, _ = destination(lat, lon, math.atan2(d_east, d_north), dist, hd, ell)
    return la, lo


def nearby_offset(lat0: float, lon0: float, lat1: float, lon1: float) -> tuple[float, float]:
    """North, east of point 1 from point 0 in metres, for points kilometres apart.

    The latitude and longitude differences times the meridian and prime-vertical radii
    at the middle latitude (Rapp 1991, Geometric Geodesy I, 3.4): the length is the
    geodesic's within a millimetre up to 2 km (tests/test_geodesy.py), without
    enu_offset's two ECEF conversions.  For a spread worked out every filter step, not
    for moving a position.
    """
    mid = 0.5 * (lat0 + lat1)
    n = (lat1 - lat0) * meridian_radius(mid)
    e = wrap_lon(lon1 - lon0) * prime_vertical_radius(mid) * math.cos(mid)
    return n, e


def metres_per_degree(lat: float) -> tuple[float, float]:
    """Length of a degree of latitude and of longitude in metres (eq. 3.15, NGA formula)."""
    m_lat = (
        111132.92
        - 559.82 * math.cos(2 * lat)
        + 1.175 * math.cos(4 * lat)
        - 0.0023 * math.cos(6 * lat)
    )
    m_lon = 111412.84 * math.cos(lat) - 93.5 * math.cos(3 * lat) + 0.118 * math.cos(5 * lat)
    return m_lat, m_lon


def wrap_lon(lon: float) -> float:
    """Longitude wrapped into [-pi, pi)."""
    if -math.pi <= lon < math.pi:
        return lon
    return (lon + math.pi) % (2.0 * math.pi) - math.pi


def enu_offset(
    lat0: float,
    lon0: float,
    hd0: float,
    lat1: float,
    lon1: float,
    hd1: float,
    ell: Ellipsoid = WGS84,
) -> tuple[float, float, float]:
    """East, north, up of point 1 in the local tangent frame at point 0 (exact, via ECEF)."""
    x0, y0, z0 = geodetic_to_ecef(lat0, lon0, hd0, 0.0, ell)
    x1, y1, z1 = geodetic_to_ecef(lat1, lon1, hd1, 0.0, ell)
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    sl, cl = math.sin(lat0), math.cos(lat0)
    so, co = math.sin(lon0), math.cos(lon0)
    e = -so * dx + co * dy
    n = -sl * co * dx - sl * so * dy + cl * dz
    u = cl * co * dx + cl * so * dy + sl * dz
    return e, n, u


def range_and_gradient(
    lat: float,
    lon: float,
    hd: float,
    lat_t: float,
    lon_t: float,
    hd_t: float,
    ell: Ellipsoid = WGS84,
) -> tuple[float, float, float]:
    """Straight-line range from a point to a target and its gradient w.r.t. the point.

    Returns (r, dr/dnorth, dr/deast): the gradient is the unit line of sight projected
    on the local north and east unit vectors at the point, per metre of displacement.
    Multiply by (M + hd) and (N + hd) cos(lat) for derivatives per radian (seed 000
    Appendix B, H).
    """
    x, y, z = geodetic_to_ecef(lat, lon, hd, 0.0, ell)
    xt, yt, zt = geodetic_to_ecef(lat_t, lon_t, hd_t, 0.0, ell)
    dx, dy, dz = x - xt, y - yt, z - zt
    r = math.sqrt(dx * dx + dy * dy + dz * dz)
    if r == 0.0:
        return 0.0, 0.0, 0.0
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    dn = (-sl * co * dx - sl * so * dy + cl * dz) / r
    de = (-so * dx + co * dy) / r
    return r, dn, de
