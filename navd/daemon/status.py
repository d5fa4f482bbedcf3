"""The daemon's health, assembled once a second from what each part says of itself: the
devices (their ports, decoders and own sections), the filter, the tick timing, the
log, the checkpoints and the zenoh session; and the list of what is not well."""

from __future__ import annotations

import typing

from navd.daemon import pace
from navd.daemon.devices.base import HealthSections
from navd.daemon.devices.modem import idle_sections
from navd.daemon.health import RECENT_S
from navd.schema import Health

if typing.TYPE_CHECKING:
    from navd.daemon.daemon import Daemon


def health_of(d: Daemon, now: float) -> Health:
    devices = {name: dev.health(now) for name, dev in d.devices.items()}
    # each device's own sections; a device navd has not says nothing, or idles
    own: HealthSections = {"temperature_c": None, "gps_utc": None, "esc": {}}
    own.update(idle_sections())
    for dev in d.devices.values():
        own.update(dev.sections())
    est = d.latest
    mode = est.mode if est else "waiting_for_gps"
    d.vitals.mode(now, mode)
    dc = d.cfg.devices
    source = {"heading": dc.ahrs, "rpm": dc.motor, "depth": dc.pressure}
    ages = {k: v for k, v in d.nav.input_ages(now).items() if source[k].enabled}
    degraded = d.vitals.problems(now, d.nav.filter.initialised, ages)
    integrity = est.integrity if est else "lost"
    if integrity != "ok" and d.nav.filter.initialised:
        why = (est.integrity_reason if est else None) or ""
        degraded.append(f"integrity {integrity}: {why}")
    for n, dev in d.devices.items():
        degraded += dev.problems(now, devices[n])
    if d.t_internal_error is not None and now - d.t_internal_error <= RECENT_S:
        degraded.append(f"internal errors {d.internal_errors}")
    if d.rlog.degraded and d.rlog.errors:
        degraded.append("log")
    if d.publisher_factory is not None and d.pub is None:
        degraded.append(f"zenoh: not open ({d.zenoh_error or 'opening'}), retrying")
    return Health(
        t=now,
        mode=mode,
        integrity=integrity if d.nav.filter.initialised else "lost",
        ok=not degraded,
        degraded=degraded,
        estimates_per_s=d.vitals.estimates_per_s(now),
        input_age_s={k: None if v is None else round(v, 3) for k, v in ages.items()},
        last_range_accepted_age_s=None
        if d.vitals.t_range_accepted is None
        else round(now - d.vitals.t_range_accepted, 3),
        devices=devices,
        pings={**own["pings"], "fused": d.fused, "last": list(d.vitals.pings)},
        modem=own["modem"],
        filter=dict(d.nav.counters),
        ticks=d.times.ticks,
        tick_overruns=d.times.overruns,
        tick_lateness_ms=d.times.lateness_ms(),
        publish_latency_ms=d.times.publish_ms(),
        log=d.rlog.section(),
        checkpoint=None if d.checkpoints is None else d.checkpoints.section(d.resumed),
        zenoh={"open": False, "error": d.zenoh_error}
        if d.pub is None
        else d.pub.section(),
        temperature_c=own["temperature_c"],
        gps_utc=own["gps_utc"],
        esc=own["esc"],
    )


async def every_second(d: Daemon) -> None:
    """Once a second: the devices' own checks, then health and the observability
    advisory, to the log and to zenoh."""
    while True:
        await pace.sleep_to_next(1.0, d.clock)
        now = d.clock()
        for dev in d.devices.values():
            dev.every_second(now)
        h = health_of(d, now)
        d.rlog.output(h)
        heading = d.latest.heading_deg if d.latest else None
        adv = d.nav.advisory(now, heading)
        d.rlog.output(adv)
        if d.pub is not None:
            d.pub.put(h)
            d.pub.put(adv)
