"""navd export: GPX valid against its XSD, KML that parses with what it should hold, CSV,
and MCAP read back with the mcap reader, channel by channel against the log."""

from __future__ import annotations

import csv
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from lxml import etree
from mcap.reader import make_reader

from navd.formats.mlog import read_measurement_log
from navd.hil.scenario import load_scenario
from navd.hil.sim_cli import write_mission
from navd.hil.world import simulate

XSD = Path(__file__).parent / "data" / "gpx-1.1.xsd"
KML = "{http://www.opengis.net/kml/2.2}"


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("export")
    write_mission(simulate(load_scenario("claytor-3"), 2), d)
    r = subprocess.run(
        [sys.executable, "-m", "navd", "export", str(d / "measurements.jsonl"),
         "--config", str(d / "config.yaml"), "--smooth", "--ellipse-every", "30",
         "--gpx", str(d / "m.gpx"), "--kml", str(d / "m.kml"), "--csv", str(d / "m.csv"),
         "--mcap", str(d / "m.mcap")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    return d


def _estimates(d: Path) -> int:
    return sum(1 for _ in csv.DictReader((d / "m.csv").open()))


def test_gpx_is_valid_gpx_1_1_with_every_track(exported: Path) -> None:
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    doc = etree.parse(str(exported / "m.gpx"))
    schema.assertValid(doc)
    ns = {"g": "http://www.topografix.com/GPX/1/1"}
    names = doc.xpath("//g:trk/g:name/text()", namespaces=ns)
    assert names == ["estimate", "smoothed", "dead reckoning", "GPS fixes", "beacon"]
    est = doc.xpath("//g:trk[g:name='estimate']//g:trkpt", namespaces=ns)
    assert len(est) == _estimates(exported)
    (wpt,) = doc.xpath("//g:wpt", namespaces=ns)  # claytor-3 surfaces once
    assert "against the first GPS fix" in wpt.findtext("g:desc", namespaces=ns)
    # no line across the dive: the fixes before it and after it are segments of their own,
    # as is dead reckoning after its reset at the first fix; the estimate runs unbroken
    def segs(name: str) -> int:
        return len(doc.xpath(f"//g:trk[g:name='{name}']/g:trkseg", namespaces=ns))

    assert segs("GPS fixes") == 2 and segs("dead reckoning") >= 2 and segs("estimate") == 1


def test_kml_has_tracks_surfacings_and_ellipses(exported: Path) -> None:
    doc = etree.parse(str(exported / "m.kml"))
    folders = [f.findtext(f"{KML}name") for f in doc.getroot().iter(f"{KML}Folder")]
    assert folders == [
        "estimate", "smoothed", "dead reckoning", "GPS fixes", "beacon", "95 % ellipses"
    ]  # fmt: skip
    marks = list(doc.getroot().iter(f"{KML}Placemark"))
    names = [m.findtext(f"{KML}name") for m in marks]
    assert names.count("GPS fixes") == 2  # before the dive and after it, no line between
    assert any(n.startswith("surfacing 1: ") for n in names)
    # every track segment and ellipse has its time, for Google Earth's slider
    for m in marks:
        if not m.findtext(f"{KML}name").startswith("surfacing"):
            assert m.find(f"{KML}TimeSpan") is not None or m.find(f"{KML}TimeStamp") is not None
    rings = list(doc.getroot().iter(f"{KML}LinearRing"))
    n = _estimates(exported)
    assert len(rings) >= n // 300  # one every 30 s at 10 Hz
    pts = rings[0].findtext(f"{KML}coordinates").split()
    assert len(pts) == 37 and pts[0] == pts[-1]  # closed


def test_mcap_holds_what_the_log_holds(exported: Path) -> None:
    log = read_measurement_log(exported / "measurements.jsonl")
    by_type = Counter(type(r).__name__.lower() for r in log.records)
    with (exported / "m.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics is not None
    topics = {c.id: c.topic for c in summary.channels.values()}
    counts = {topics[i]: n for i, n in summary.statistics.channel_message_counts.items()}
    schemas = {topics[c.id]: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert schemas["/nav/estimate"] == "foxglove.LocationFix"
    assert schemas["/nav/gps"] == "foxglove.LocationFix"
    assert schemas["/nav/log"] == "foxglove.Log"
    assert counts["/nav/estimate"] == counts["/nav/smoothed"] == _estimates(exported)
    assert counts["/sensors/heading"] == by_type["heading"]
    assert counts["/sensors/rpm"] == by_type["rpm"]
    assert counts["/sensors/range"] == counts["/nav/range"] == by_type["range"]
    assert counts["/nav/log"] >= 3  # mode changes, integrity, the surfacing
    # JSON channels carry their fields' schema (navd/schema.py), for a viewer's plots
    import json

    by_topic = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    rng = json.loads(by_topic["/nav/range"].data)
    assert rng["properties"]["accepted"] == {"type": "boolean"}
    assert {"type": "number"} in rng["properties"]["residual_m"]["anyOf"]
    head = json.loads(by_topic["/sensors/heading"].data)
    assert head["properties"]["deg"] == {"type": "number"}


def test_a_daemon_logs_ticks_export_to_mcap(tmp_path: Path) -> None:
    """A daemon's own log holds its ticks (estimate lines): they are steps, not readings."""
    from navd.formats import jsonlines
    from navd.formats.mlog import record_to_json

    d = tmp_path / "m"
    m = simulate(load_scenario("demo"), 1)
    write_mission(m, d)
    head = (d / "measurements.jsonl").read_text().splitlines(keepends=True)[0]
    lines, k = [head], 1
    for rec in m.records:
        while k * 0.1 < rec.t:
            lines.append(jsonlines.dumps_line({"type": "estimate", "t": round(k * 0.1, 9)}))
            k += 1
        lines.append(jsonlines.dumps_line(record_to_json(rec)))
    log = tmp_path / "navd-daemon.jsonl"
    log.write_text("".join(lines))
    r = subprocess.run(
        [sys.executable, "-m", "navd", "export", str(log), "--config", str(d / "config.yaml"),
         "--mcap", str(tmp_path / "d.mcap")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    with (tmp_path / "d.mcap").open("rb") as fh:
        topics = Counter(ch.topic for _, ch, _ in make_reader(fh).iter_messages())
    assert topics["/nav/estimate"] > 1000 and "/sensors/heading" in topics


@pytest.mark.parametrize("cmd", ["replay", "export", "calibrate"])
def test_no_command_writes_over_its_input(tmp_path: Path, cmd: str) -> None:
    write_mission(simulate(load_scenario("demo"), 1), tmp_path)
    log = tmp_path / "measurements.jsonl"
    before = log.read_bytes()
    args = {
        "replay": ["replay", str(log), "--out", str(log)],
        "export": ["export", str(log), "--csv", str(tmp_path / "." / "measurements.jsonl")],
        "calibrate": ["calibrate", "compass", str(log), "--out", str(log)],
    }[cmd]
    r = subprocess.run(
        [sys.executable, "-m", "navd", *args], capture_output=True, text=True, timeout=120
    )
    assert r.returncode == 2 and "is the input" in r.stderr, r.stderr
    assert log.read_bytes() == before


def test_export_refuses_a_directory_and_a_zero_ellipse_interval(tmp_path: Path) -> None:
    write_mission(simulate(load_scenario("demo"), 1), tmp_path)
    log = str(tmp_path / "measurements.jsonl")
    for args, said in (
        (["--mcap", str(tmp_path)], "is a directory"),
        (["--kml", str(tmp_path / "m.kml"), "--ellipse-every", "0"], "must be more than 0"),
    ):
        r = subprocess.run(
            [sys.executable, "-m", "navd", "export", log, *args],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert r.returncode == 2 and said in r.stderr, r.stderr
        assert said in r.stderr.strip().splitlines()[-1] and "Traceback" not in r.stderr


def test_gis_and_csv_need_no_extra_and_mcap_names_its_own(exported: Path, tmp_path: Path) -> None:
    """As after a plain ``pip install navd``: GeographicLib, matplotlib and the Foxglove SDK
    absent.  GPX, KML and CSV are written; MCAP names the ``foxglove`` extra."""
    blocked = (
        "import sys\n"
        "for m in ('geographiclib', 'matplotlib', 'foxglove', 'pyproj'):\n"
        "    sys.modules[m] = None\n"
        "from navd.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    base = [sys.executable, "-c", blocked, "export", str(exported / "measurements.jsonl"),
            "--config", str(exported / "config.yaml")]  # fmt: skip
    r = subprocess.run(
        [*base, "--gpx", str(tmp_path / "m.gpx"), "--kml", str(tmp_path / "m.kml"),
         "--csv", str(tmp_path / "m.csv")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    gpx = etree.parse(str(tmp_path / "m.gpx"))
    assert gpx.getroot().findall("{http://www.topografix.com/GPX/1/1}trk")
    assert _estimates(tmp_path) == _estimates(exported)
    r = subprocess.run(
        [*base, "--mcap", str(tmp_path / "m.mcap")], capture_output=True, text=True, timeout=120
    )
    assert r.returncode == 2
    assert "pip install 'navd[foxglove]'" in r.stderr and "Traceback" not in r.stderr


def test_a_live_daemons_log_exports_and_every_json_message_fits_its_schema(
    tmp_path: Path,
) -> None:
    """A daemon on the emulated vehicle writes its log; exported, /nav/health comes through
    and a JSON-schema validator accepts every JSON message against its channel's schema."""
    import json
    import time

    from jsonschema import Draft202012Validator

    from navd.hil.bench_vehicle import BenchVehicle

    v = BenchVehicle(tmp_path / "v", subprocess.DEVNULL)
    try:
        time.sleep(25.0)  # a few pings, health every second
    finally:
        v.stop()
        v.kill()
    out = tmp_path / "live.mcap"
    r = subprocess.run(
        [sys.executable, "-m", "navd", "export", str(v.logfile()), "--config", str(v.config),
         "--mcap", str(out), "--gpx", str(tmp_path / "live.gpx"), "--csv", str(tmp_path / "l.csv"),
         "--kml", str(tmp_path / "live.kml")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    etree.XMLSchema(etree.parse(str(XSD))).assertValid(etree.parse(str(tmp_path / "live.gpx")))
    # and an independent GPX reader sees the same tracks, each point with its time
    import gpxpy

    gpx = gpxpy.parse((tmp_path / "live.gpx").read_text())
    tracks = {t.name: t for t in gpx.tracks}
    assert {"estimate", "dead reckoning", "GPS fixes"} <= set(tracks)
    est_points = [p for seg in tracks["estimate"].segments for p in seg.points]
    assert len(est_points) == sum(1 for _ in csv.DictReader((tmp_path / "l.csv").open()))
    assert all(p.time is not None for p in est_points)
    # and an independent KML reader: every track segment a line (or a point) with its time
    from fastkml import KML as FastKML

    def features(f):
        for x in getattr(f, "features", None) or []:
            yield x
            yield from features(x)

    marks = [x for x in features(FastKML.parse(str(tmp_path / "live.kml")))
             if type(x).__name__ == "Placemark" and x.name in tracks]  # fmt: skip
    assert {m.name for m in marks} == set(tracks)
    assert all(m.times is not None and m.geometry is not None for m in marks)
    seen: Counter[str] = Counter()
    with out.open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            if channel.message_encoding != "json":
                continue
            Draft202012Validator(json.loads(schema.data)).validate(json.loads(message.data))
            seen[channel.topic] += 1
    assert seen["/nav/health"] >= 10 and seen["/nav/range"] >= 1
    assert seen["/sensors/attitude"] > 100 and seen["/sensors/gps"] > 0, seen
