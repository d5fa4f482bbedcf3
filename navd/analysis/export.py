"""``navd export``: a mission for the tools vehicle teams already use.

The log (a measurement log or the daemon's own) is run through the same navigator
as ``navd replay``; what comes out (estimates, the smoothed track when asked, range
decisions, dead reckoning), with the log's GPS fixes, raw sensor records and health,
is written as GPX, KML or CSV (navd/formats/gis.py) for GIS tools, or as MCAP with
Foxglove's schemas (navd/formats/foxglove_mcap.py).
"""

from __future__ import annotations

from pathlib import Path

from navd.analysis.replay import run_navigator
from navd.analysis.surfacing import surfacings
from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.formats.mission import Mission
from navd.formats.mlog import MeasurementLog, log_epoch, read_measurement_log
from navd.records import Gps
from navd.schema import Estimate, split_outputs
from navd.settings import Config


def _health_lines(paths: list[Path]) -> list[JsonObject]:
    out = []
    for p in paths:
        with p.open("rb") as fh:
            for line in fh:
                if b'"health"' not in line:
                    continue
                try:
                    obj = jsonlines.object_or_none(jsonlines.loads(line))
                except jsonlines.DecodeError:
                    continue
                if obj is not None and obj.get("type") == "health":
                    out.append(obj)
    return out


def load_mission(paths: list[str | Path], cfg: Config, smooth: bool = False) -> Mission:
    log = MeasurementLog({}, [], [])
    for p in paths:
        part = read_measurement_log(p)
        log.header = log.header or part.header
        log.records.extend(part.records)
    result = run_navigator(log, cfg, smooth=smooth)
    smoothed: list[Estimate] = []
    if smooth:
        smoothed, _ = split_outputs(result.outputs)
        est, dec = split_outputs(result.filtered)
    else:
        est, dec = split_outputs(result.outputs)
    fixes = [r for r in log.records if isinstance(r, Gps) and r.fix and r.lat is not None]
    return Mission(
        est,
        dec,
        fixes,
        log.records,
        log_epoch(log.header) or 0.0,
        smoothed,
        _health_lines([Path(p) for p in paths]),
        surfacings(est, fixes),
    )
