"""A mission as MCAP with Foxglove's well-known schemas (``navd export --mcap``).

Foxglove's Map, Plot and Raw Messages panels open it without configuration:

* ``/nav/estimate``, ``/nav/smoothed``, ``/nav/dead_reckoning``, ``/nav/gps``,
  ``/nav/beacon``: ``foxglove.LocationFix`` (the estimate with its covariance);
* ``/nav/range`` (the range decisions), ``/nav/health`` (the daemon's, from its log)
  and ``/sensors/<type>`` (every raw measurement record): JSON with a JSON schema;
* ``/nav/log``: ``foxglove.Log`` for events (mode and integrity changes,
  re-acquisitions, surfacing errors).

Written with the Foxglove SDK (the ``foxglove`` extra), in a context of its own so
that exporting never mixes with a live server's channels.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from navd.formats.jsonschema import schema_of
from navd.formats.mission import Mission
from navd.formats.mlog import record_to_json
from navd.records import TYPE_NAMES
from navd.schema import Estimate, Health, RangeDecision, to_dict

if TYPE_CHECKING:  # the SDK is an extra, imported where it is used
    import foxglove
    from foxglove.channels import LocationFixChannel
    from foxglove.messages import LocationFix


def _ns(m: Mission, t: float) -> int:
    return int(round((m.epoch_s + t) * 1e9))


def location_fix(
    lat: float, lon: float, depth: float, e: Estimate | None, t_ns: int
) -> LocationFix:
    """A ``foxglove.LocationFix``; with the estimate's covariance (ENU, metres²) when given."""
    from foxglove.messages import LocationFix, LocationFixPositionCovarianceType, Timestamp

    stamp = Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
    if e is None:
        return LocationFix(
            timestamp=stamp, frame_id="wgs84", latitude=lat, longitude=lon, altitude=-depth
        )
    vn, ve, c = e.std_n**2, e.std_e**2, e.cov_ne
    return LocationFix(
        timestamp=stamp,
        frame_id="wgs84",
        latitude=lat,
        longitude=lon,
        altitude=-depth,
        position_covariance=[ve, c, 0.0, c, vn, 0.0, 0.0, 0.0, 0.01],
        position_covariance_type=LocationFixPositionCovarianceType.Known,
    )


def _events(m: Mission) -> list[tuple[float, str, str]]:
    """(t, level, message) worth a line in Foxglove's log panel."""
    out = []
    mode = integrity = None
    for e in m.estimates:
        if e.mode != mode:
            out.append((e.t, "info", f"mode {e.mode}"))
            mode = e.mode
        if e.integrity != integrity:
            level = {"ok": "info", "degraded": "warning"}.get(e.integrity, "error")
            why = f": {e.integrity_reason}" if e.integrity_reason else ""
            out.append((e.t, level, f"integrity {e.integrity}{why}"))
            integrity = e.integrity
    for d in m.decisions:
        if d.reason == "gate_reacquire":
            out.append((d.t, "warning", "re-acquired: the recent ranges agreed on a correction"))
    for s in m.surfacings:
        out.append((s.t, "info", f"surfaced: {s.error_m:.1f} m from the first GPS fix"))
    return sorted(out, key=lambda x: x[0])


def _located(
    m: Mission,
) -> Iterator[tuple[str, float, float, float, float, Estimate | None]]:
    """(topic, t, lat, lon, depth, the estimate for its covariance) of every position."""
    for e in m.estimates:
        yield "/nav/estimate", e.t, e.lat, e.lon, e.depth, e
        if e.dr_lat is not None and e.dr_lon is not None:
            yield "/nav/dead_reckoning", e.t, e.dr_lat, e.dr_lon, e.depth, None
    for e in m.smoothed:
        yield "/nav/smoothed", e.t, e.lat, e.lon, e.depth, e
    for g in m.fixes:
        if g.lat is not None and g.lon is not None:
            yield "/nav/gps", g.t, g.lat, g.lon, 0.0, None
    for d in m.decisions:
        if d.beacon_lat is not None and d.beacon_lon is not None:
            yield "/nav/beacon", d.t, d.beacon_lat, d.beacon_lon, d.beacon_depth or 0.0, None


def write_mcap(m: Mission, path: str | Path) -> dict[str, int]:
    """Write the mission; returns the messages written per topic."""
    import foxglove
    from foxglove.channels import LocationFixChannel, LogChannel
    from foxglove.messages import Log, LogLevel, Timestamp

    ctx = foxglove.Context()
    counts: dict[str, int] = {}
    writer = foxglove.open_mcap(str(path), allow_overwrite=True, context=ctx)
    try:
        fix_channels: dict[str, LocationFixChannel] = {}

        def fix(
            topic: str, t: float, lat: float, lon: float, depth: float, e: Estimate | None = None
        ) -> None:
            ch = fix_channels.get(topic)
            if ch is None:
                ch = fix_channels[topic] = LocationFixChannel(topic, context=ctx)
            t_ns = _ns(m, t)
            ch.log(location_fix(lat, lon, depth, e, t_ns), log_time=t_ns)
            counts[topic] = counts.get(topic, 0) + 1

        for topic, t, lat, lon, depth, e in _located(m):
            fix(topic, t, lat, lon, depth, e)

        json_channels: dict[str, foxglove.Channel] = {}

        def as_json(topic: str, t: float, body: dict[str, object], cls: type) -> None:
            ch = json_channels.get(topic)
            if ch is None:
                schema = schema_of(cls, title=topic)
                ch = json_channels[topic] = foxglove.Channel(
                    topic, schema=schema, message_encoding="json", context=ctx
                )
            ch.log(body, log_time=_ns(m, t))
            counts[topic] = counts.get(topic, 0) + 1

        for d in m.decisions:
            as_json("/nav/range", d.t, to_dict(d), RangeDecision)
        for h in m.health:
            if isinstance(t_h := h.get("t"), int | float):
                as_json("/nav/health", t_h, h, Health)
        for rec in m.records:
            if type(rec) in TYPE_NAMES:  # not a daemon log's ticks: its steps, not readings
                topic = f"/sensors/{TYPE_NAMES[type(rec)]}"
                as_json(topic, rec.t, record_to_json(rec), type(rec))

        log = LogChannel("/nav/log", context=ctx)
        levels = {"info": LogLevel.Info, "warning": LogLevel.Warning, "error": LogLevel.Error}
        for t, level, text in _events(m):
            t_ns = _ns(m, t)
            stamp = Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
            log.log(
                Log(timestamp=stamp, level=levels[level], message=text, name="navd"), log_time=t_ns
            )
            counts["/nav/log"] = counts.get("/nav/log", 0) + 1
    finally:
        writer.close()
    return counts
