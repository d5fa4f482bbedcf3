"""GPX 1.1, KML 2.2 and CSV: a mission for QGIS, Google Earth and spreadsheets.

Tracks: the estimate, the smoothed estimate (when there is one), dead reckoning, the
GPS fixes and the beacon as its replies placed it; points: each surfacing with the
distance between where navd thought the vehicle was and the first GPS fix.  KML also
draws the 95 % position ellipse every ``ellipse_every_s``.

A track is cut into segments where it has a gap in time (GPS fixes over a dive, the
beacon while its location line was down) or jumps (dead reckoning reset at a fix), so
a viewer draws no line that the vehicle never ran: GPX ``trkseg``s, and in KML one
placemark per segment, each with its ``TimeSpan`` for Google Earth's time slider.
"""

from __future__ import annotations

import csv
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

from navd import geodesy
from navd.filter.common import principal_axes
from navd.formats.mission import Mission
from navd.schema import Estimate, to_dict

GPX_NS = "http://www.topografix.com/GPX/1/1"
KML_NS = "http://www.opengis.net/kml/2.2"
CHI2_2DOF_95 = 5.991  # the 95 % quantile of chi-square with 2 degrees of freedom
ELLIPSE_POINTS = 36


def _iso(m: Mission, t: float) -> str:
    return m.utc(t).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def _tracks(m: Mission) -> list[tuple[str, list[tuple[float, float, float, float]]]]:
    """(name, [(t, lat, lon, depth)]) for every track the mission has."""
    out = [("estimate", [(e.t, e.lat, e.lon, e.depth) for e in m.estimates])]
    if m.smoothed:
        out.append(("smoothed", [(e.t, e.lat, e.lon, e.depth) for e in m.smoothed]))
    dr = [
        (e.t, e.dr_lat, e.dr_lon, e.depth)
        for e in m.estimates
        if e.dr_lat is not None and e.dr_lon is not None
    ]
    if dr:
        out.append(("dead reckoning", dr))
    gps = [(f.t, f.lat, f.lon, 0.0) for f in m.fixes if f.lat is not None and f.lon is not None]
    if gps:
        out.append(("GPS fixes", gps))
    beacon = [
        (d.t, d.beacon_lat, d.beacon_lon, d.beacon_depth or 0.0)
        for d in m.decisions
        if d.beacon_lat is not None and d.beacon_lon is not None
    ]
    if beacon:
        out.append(("beacon", beacon))
    return out


# a gap longer than this in a track (beacon replies come every 10 s or so) starts a new
# segment, and in dead reckoning (reset to each fix) a step faster than a vehicle moves
_GAP_S = {"beacon": 120.0}
_JUMPS = ("dead reckoning",)
_DEFAULT_GAP_S = 5.0
_MAX_SPEED_MPS = 15.0
_JUMP_SLACK_M = 20.0


def segments(
    name: str, pts: list[tuple[float, float, float, float]]
) -> list[list[tuple[float, float, float, float]]]:
    """The track's points split where time has a gap or the position jumps."""
    gap = _GAP_S.get(name, _DEFAULT_GAP_S)
    out: list[list[tuple[float, float, float, float]]] = []
    prev = None
    for p in pts:
        if prev is not None:
            dt = p[0] - prev[0]
            jump = False
            if name in _JUMPS:
                e, n, _ = geodesy.enu_offset(
                    math.radians(prev[1]), math.radians(prev[2]), 0.0,
                    math.radians(p[1]), math.radians(p[2]), 0.0,
                )  # fmt: skip
                jump = math.hypot(e, n) > _JUMP_SLACK_M + _MAX_SPEED_MPS * max(dt, 0.0)
            if dt > gap or jump:
                prev = None
        if prev is None:
            out.append([])
        out[-1].append(p)
        prev = p
    return out


def write_gpx(m: Mission, path: str | Path) -> None:
    ET.register_namespace("", GPX_NS)
    q = f"{{{GPX_NS}}}"
    gpx = ET.Element(f"{q}gpx", {"version": "1.1", "creator": "navd"})
    meta = ET.SubElement(gpx, f"{q}metadata")
    ET.SubElement(meta, f"{q}name").text = "navd mission"
    if m.estimates:
        ET.SubElement(meta, f"{q}time").text = _iso(m, m.estimates[0].t)
    for i, s in enumerate(m.surfacings, 1):
        w = ET.SubElement(gpx, f"{q}wpt", {"lat": f"{s.lat:.8f}", "lon": f"{s.lon:.8f}"})
        ET.SubElement(w, f"{q}time").text = _iso(m, s.t)
        ET.SubElement(w, f"{q}name").text = f"surfacing {i}"
        ET.SubElement(w, f"{q}desc").text = (
            f"error {s.error_m:.1f} m against the first GPS fix, {s.after_s:.0f} s later"
        )
    for name, pts in _tracks(m):
        trk = ET.SubElement(gpx, f"{q}trk")
        ET.SubElement(trk, f"{q}name").text = name
        for part in segments(name, pts):
            seg = ET.SubElement(trk, f"{q}trkseg")
            for t, lat, lon, depth in part:
                p = ET.SubElement(seg, f"{q}trkpt", {"lat": f"{lat:.8f}", "lon": f"{lon:.8f}"})
                ET.SubElement(p, f"{q}ele").text = f"{-depth:.2f}"  # below the surface
                ET.SubElement(p, f"{q}time").text = _iso(m, t)
    ET.ElementTree(gpx).write(path, encoding="UTF-8", xml_declaration=True)


def ellipse95(e: Estimate) -> list[tuple[float, float]]:
    """The 95 % position ellipse of an estimate, as (lat, lon) degrees around it."""
    vn, ve, c = e.std_n**2, e.std_e**2, e.cov_ne
    # eigen-decomposition of [[vn, c], [c, ve]]
    l1, l2, theta = principal_axes(vn, ve, c)  # theta: the major axis, from north
    l1, l2 = max(l1, 0.0), max(l2, 0.0)
    a, b = math.sqrt(CHI2_2DOF_95 * l1), math.sqrt(CHI2_2DOF_95 * l2)
    lat0, lon0 = math.radians(e.lat), math.radians(e.lon)
    pts = []
    for k in range(ELLIPSE_POINTS + 1):
        u = 2.0 * math.pi * k / ELLIPSE_POINTS
        x, y = a * math.cos(u), b * math.sin(u)  # along the major and the minor axis
        dn = x * math.cos(theta) - y * math.sin(theta)
        de = x * math.sin(theta) + y * math.cos(theta)
        lat, lon = geodesy.offset_position(lat0, lon0, dn, de, 0.0)
        pts.append((math.degrees(lat), math.degrees(lon)))
    return pts


def _coords(pts: Iterable[tuple[float, float]]) -> str:
    return " ".join(f"{lon:.8f},{lat:.8f},0" for lat, lon in pts)


def write_kml(m: Mission, path: str | Path, ellipse_every_s: float = 60.0) -> None:
    ET.register_namespace("", KML_NS)
    q = f"{{{KML_NS}}}"
    kml = ET.Element(f"{q}kml")
    doc = ET.SubElement(kml, f"{q}Document")
    ET.SubElement(doc, f"{q}name").text = "navd mission"
    colours = {"estimate": "ff00ff00", "smoothed": "ffffff00", "dead reckoning": "ffff00ff"}
    colours |= {"GPS fixes": "ff0000ff", "beacon": "ff00ffff"}
    for name, pts in _tracks(m):
        folder = ET.SubElement(doc, f"{q}Folder")
        ET.SubElement(folder, f"{q}name").text = name
        for part in segments(name, pts):
            pm = ET.SubElement(folder, f"{q}Placemark")
            ET.SubElement(pm, f"{q}name").text = name
            span = ET.SubElement(pm, f"{q}TimeSpan")
            ET.SubElement(span, f"{q}begin").text = _iso(m, part[0][0])
            ET.SubElement(span, f"{q}end").text = _iso(m, part[-1][0])
            style = ET.SubElement(ET.SubElement(pm, f"{q}Style"), f"{q}LineStyle")
            ET.SubElement(style, f"{q}color").text = colours.get(name, "ffffffff")
            if len(part) == 1:  # a LineString needs two points
                pt = ET.SubElement(pm, f"{q}Point")
                ET.SubElement(pt, f"{q}coordinates").text = _coords([(part[0][1], part[0][2])])
                continue
            line = ET.SubElement(pm, f"{q}LineString")
            ET.SubElement(line, f"{q}coordinates").text = _coords((p[1], p[2]) for p in part)
    for i, s in enumerate(m.surfacings, 1):
        pm = ET.SubElement(doc, f"{q}Placemark")
        ET.SubElement(pm, f"{q}name").text = f"surfacing {i}: {s.error_m:.1f} m"
        ET.SubElement(pm, f"{q}description").text = (
            f"last submerged estimate at {_iso(m, s.t)}; the first GPS fix {s.after_s:.0f} s "
            f"later was {s.error_m:.1f} m away"
        )
        pt = ET.SubElement(pm, f"{q}Point")
        ET.SubElement(pt, f"{q}coordinates").text = _coords([(s.lat, s.lon)])
    ellipses = ET.SubElement(doc, f"{q}Folder")
    ET.SubElement(ellipses, f"{q}name").text = "95 % ellipses"
    t_next = -math.inf
    for e in m.estimates:
        if e.t < t_next:
            continue
        t_next = e.t + ellipse_every_s
        pm = ET.SubElement(ellipses, f"{q}Placemark")
        ET.SubElement(pm, f"{q}name").text = _iso(m, e.t)
        when = ET.SubElement(ET.SubElement(pm, f"{q}TimeStamp"), f"{q}when")
        when.text = _iso(m, e.t)
        poly = ET.SubElement(ET.SubElement(pm, f"{q}Polygon"), f"{q}outerBoundaryIs")
        ring = ET.SubElement(poly, f"{q}LinearRing")
        ET.SubElement(ring, f"{q}coordinates").text = _coords(ellipse95(e))
    ET.ElementTree(kml).write(path, encoding="UTF-8", xml_declaration=True)


CSV_FIELDS = (
    "utc", "t", "lat", "lon", "depth", "std_n", "std_e", "cov_ne", "current_n", "current_e",
    "mode", "integrity", "dr_lat", "dr_lon", "smoothed_lat", "smoothed_lon",
)  # fmt: skip


def write_csv(m: Mission, path: str | Path) -> None:
    smoothed = {e.t: e for e in m.smoothed}
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for e in m.estimates:
            s = smoothed.get(e.t)
            row = {**to_dict(e), "utc": _iso(m, e.t)}
            row["smoothed_lat"], row["smoothed_lon"] = (s.lat, s.lon) if s else ("", "")
            w.writerow(row)
