"""The world simulator: truth for a mission and what each sensor would have said.

Pure computation, no I/O: the same model later drives the device emulators in
real time.  Truth is propagated on GeographicLib's ellipsoid (its Direct for long
offsets, a midpoint step of the geodesic's equations checked against Direct for the
sensor steps) and placed in ECEF with PROJ: deliberately not navd's own geodesy, so
a shared bug cannot make a test pass.

The simulated vehicle follows legs at a commanded speed and depth with a turn-rate
limit through a water current that may vary in time; a boat carries the beacon
(with its GPS error, transducer swing and depth, its own motion and drift); the
acoustic channel pings every ``ping_interval_s`` with the true round-trip timing,
drops in bursts (Gilbert-Elliott), multipath outliers that read long, corrupted
beacon positions in replies, range noise and the modem's sound speed against the
water's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geographiclib.geodesic import Geodesic
from pyproj import Transformer

from navd.acoustics import coppens
from navd.filter.compass import deviation_deg
from navd.formats.truth import TruthSample
from navd.hil.scenario import Scenario
from navd.records import (
    Attitude,
    Depth,
    Gps,
    Heading,
    Range,
    Record,
    Rpm,
    TravelTime,
    Velocity,
)

_GEOD = Geodesic.WGS84
_A, _E2 = _GEOD.a, _GEOD.f * (2.0 - _GEOD.f)
_SHORT_STEP_M = 100.0  # up to here, a step of the geodesic's equations replaces Direct
# WGS-84 geographic 3-D (EPSG:4979) to geocentric (EPSG:4978), PROJ as the reference.
_ECEF = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
_GPS_SURFACE_DEPTH_M = 0.2  # the antenna is out of the water above this depth
# the transducer's swing on its rope: an AR(1) per step, this memory and step size (a
# fraction of swing_m per square-root second), held within swing_m
SWING_MEMORY = 0.98
SWING_STEP = 0.2


@dataclass(slots=True)
class Mission:
    scenario: Scenario
    seed: int
    truth: list[TruthSample]
    records: list[Record]
    pings: int
    replies: int
    channel: AcousticChannel
    # what the crew's config gets from this mission (surveyed transponder positions)
    config_overrides: dict[str, object] = field(default_factory=dict)


def _wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


class _Plan:
    """Commanded heading, speed and depth over time."""

    def __init__(self, sc: Scenario) -> None:
        v = sc.vehicle
        self.v = v
        t = 0.0
        self.surface_legs = []
        for leg in v.surface_legs:
            self.surface_legs.append((t, t + leg.duration_s, leg))
            t += leg.duration_s
        self.t_dive = t + v.surface_before_s
        self.descent = v.depth_m / v.dive_rate_mps
        t = self.t_dive
        self.legs = []
        for leg in v.legs:
            self.legs.append((t, t + leg.duration_s, leg))
            t += leg.duration_s
        self.t_up = t  # end of the last leg: start ascending
        self.t_surface = t + self.descent
        self.t_end = self.t_surface + v.surface_after_s

    def command(self, t: float) -> tuple[float | None, float, float]:
        """(heading_deg or None to hold, speed, depth) commanded at t."""
        v = self.v
        for t0, t1, leg in self.surface_legs:
            if t0 <= t < t1:
                return leg.heading_deg, leg.speed_mps or v.speed_mps, 0.0
        if t < self.t_dive or t >= self.t_surface:
            return None, 0.0, 0.0
        if t >= self.t_up:
            return None, v.speed_mps, v.depth_m * max(0.0, 1.0 - (t - self.t_up) / self.descent)
        depth = min(v.depth_m, (t - self.t_dive) * v.dive_rate_mps)
        for t0, t1, leg in self.legs:
            if t0 <= t < t1:
                if leg.depth_m is not None:  # the depth rate limit makes the transition
                    depth = leg.depth_m
                return leg.heading_deg, leg.speed_mps or v.speed_mps, depth
        return None, v.speed_mps, depth  # pragma: no cover


def current_at(sc: Scenario, t: float) -> tuple[float, float]:
    c = sc.current
    phase = 2.0 * math.pi * t / c.tidal_period_s + math.radians(c.tidal_phase_deg)
    speed = c.speed_mps + c.tidal_amplitude_mps * math.sin(phase)
    toward = math.radians(c.toward_deg + c.veer_deg_per_hour * t / 3600.0)
    return speed * math.cos(toward), speed * math.sin(toward)


def _dvl_records(
    t: float,
    s: Any,
    rng: np.random.Generator,
    heading: float,
    hmag: float,
    speed: float,
    cn: float,
    ce: float,
    w: float,
) -> list[Record]:
    """Bottom-locked DVL: velocity over ground in the body frame, with scale error, noise and
    spikes; the AHRS's full attitude (level flight: roll and pitch are noise)."""
    psi = math.radians(heading)
    vn = speed * math.cos(psi) + cn
    ve = speed * math.sin(psi) + ce
    u = vn * math.cos(psi) + ve * math.sin(psi)
    v = -vn * math.sin(psi) + ve * math.cos(psi)
    k = 1.0 + s.dvl_scale_error
    vel = [k * x + rng.normal(0.0, s.dvl_noise_mps) for x in (u, v, w)]
    if rng.random() < s.dvl_spike_prob:
        vel[0] += float(rng.choice([-1, 1]) * rng.uniform(1.0, 3.0))
    roll, pitch = rng.normal(0.0, 0.3, 2)
    return [Velocity(t, *vel), Attitude(t, float(roll), float(pitch), hmag % 360.0)]


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    return np.array(_ECEF.transform(lon, lat, h))


def _offset(lat: float, lon: float, dn: float, de: float) -> tuple[float, float]:
    """The end of the geodesic from (lat, lon) that starts ``dn`` north and ``de`` east."""
    d = math.hypot(dn, de)
    if d == 0.0:
        return lat, lon
    if d > _SHORT_STEP_M:
        r = _GEOD.Direct(lat, lon, math.degrees(math.atan2(de, dn)), d)
        return r["lat2"], _wrap_deg(r["lon2"])
    return _short_step(lat, lon, dn, de, d)


def _short_step(lat: float, lon: float, dn: float, de: float, d: float) -> tuple[float, float]:
    """One midpoint (second-order Runge-Kutta) step of the geodesic's equations.

    d(lat)/ds = cos(az)/M, d(lon)/ds = sin(az)/(N cos(lat)), d(az)/ds = sin(az) tan(lat)/N,
    with M and N the meridian and prime-vertical radii of curvature (Rapp 1991, Geometric
    Geodesy I, sections 3.4-3.5), written here rather than taken from navd.geodesy (see
    the module's docstring).  Against GeographicLib's Direct the end lies within 1e-7 m
    for the sensor steps up to 10 m, and within 1e-6 m up to 100 m, to 84 degrees of
    latitude (tests/test_world.py); Direct, called four times a sample, was nearly all
    of the simulator's time.
    """
    phi = math.radians(lat)
    ca, sa = dn / d, de / d
    h = 0.5 * d
    w = math.sqrt(1.0 - _E2 * math.sin(phi) ** 2)
    n_rad = _A / w
    m_rad = n_rad * (1.0 - _E2) / (w * w)
    phi_m = phi + h * ca / m_rad
    az_m = math.atan2(sa, ca) + h * sa * math.tan(phi) / n_rad
    ca_m, sa_m = math.cos(az_m), math.sin(az_m)
    w = math.sqrt(1.0 - _E2 * math.sin(phi_m) ** 2)
    n_rad = _A / w
    m_rad = n_rad * (1.0 - _E2) / (w * w)
    lat2 = math.degrees(phi + d * ca_m / m_rad)
    lon2 = lon + math.degrees(d * sa_m / (n_rad * math.cos(phi_m)))
    return lat2, _wrap_deg(lon2)


def simulate(sc: Scenario, seed: int) -> Mission:
    """Run the whole mission; truth at the sensor rate and every sensor record, time-ordered."""
    rng = np.random.default_rng(seed)
    plan = _Plan(sc)
    s = sc.sensors
    b = sc.boat
    dt = 1.0 / s.rate_hz
    n_steps = int(math.floor(plan.t_end / dt)) + 1

    lat, lon = sc.vehicle.lat, sc.vehicle.lon
    first = next((leg.heading_deg for leg in sc.vehicle.legs), 0.0)
    heading = first % 360.0
    depth = 0.0
    boat_lat, boat_lon = _offset(lat, lon, b.north_m, b.east_m)
    boat_course = b.heading_deg
    gps_err = rng.normal(0.0, b.gps_std_m, 2)
    swing = np.zeros(2)
    truth: list[TruthSample] = []
    boat_gps: list[tuple[float, float]] = []
    transducer: list[tuple[float, float]] = []
    records: list[Record] = []
    gps_was_up = True
    t_last_surfaced = -1e9  # the GPS was warm before the mission starts
    phi_gm = math.exp(-dt / b.gps_corr_s)

    for k in range(n_steps):
        t = k * dt
        cmd_heading, speed, cmd_depth = plan.command(t)
        # vehicle dynamics: turn-rate limit, depth rate limit
        if cmd_heading is not None:
            err = _wrap_deg(cmd_heading - heading)
            step = math.copysign(min(abs(err), sc.vehicle.turn_rate_deg_s * dt), err)
            heading = (heading + step) % 360.0
        ddepth = cmd_depth - depth
        depth += math.copysign(min(abs(ddepth), sc.vehicle.dive_rate_mps * dt), ddepth)
        cn, ce = current_at(sc, t)
        truth.append(TruthSample(t, lat, lon, depth, heading, speed, cn, ce, boat_lat, boat_lon))
        # boat GPS (Gauss-Markov error) and transducer swing
        gps_err = phi_gm * gps_err + math.sqrt(1 - phi_gm**2) * rng.normal(0.0, b.gps_std_m, 2)
        blat, blon = _offset(boat_lat, boat_lon, gps_err[0], gps_err[1])
        boat_gps.append((blat, blon))
        if b.swing_m > 0:
            step = SWING_STEP * b.swing_m * math.sqrt(dt)
            swing = SWING_MEMORY * swing + rng.normal(0.0, step, 2)
            norm = float(np.hypot(*swing))
            if norm > b.swing_m:
                swing *= b.swing_m / norm
        transducer.append(_offset(boat_lat, boat_lon, float(swing[0]), float(swing[1])))

        # sensors at this instant
        h_m = heading - s.declination_deg
        dev = deviation_deg(s.compass_deviation_deg, h_m)
        hmag = h_m + s.compass_bias_deg + dev + rng.normal(0, s.compass_noise_deg)
        records.append(Heading(t, hmag % 360.0))
        rpm = speed * s.rpm_per_mps + (rng.normal(0, s.rpm_noise) if speed > 0 else 0.0)
        records.append(Rpm(t, max(0.0, rpm)))
        records.append(Depth(t, depth + rng.normal(0, s.depth_noise_m)))
        if s.dvl:
            records.extend(_dvl_records(t, s, rng, heading, hmag, speed, cn, ce, ddepth / dt))
        at_surface = depth < _GPS_SURFACE_DEPTH_M
        if at_surface and not gps_was_up:
            t_last_surfaced = t
        gps_was_up = at_surface
        if at_surface and k % max(1, round(s.rate_hz)) == 0:
            since = t - t_last_surfaced
            if since < s.gps_acquire_s:
                records.append(Gps(t, None, None, None, 0, None))
            else:
                warm = max(0.0, 1.0 - (since - s.gps_acquire_s) / max(s.gps_warmup_s, 1e-9))
                std = s.gps_std_m + warm * s.gps_warmup_std_m
                glat, glon = _offset(lat, lon, *rng.normal(0.0, std, 2))
                records.append(
                    Gps(
                        t, glat, glon, sc.surface_altitude_m + rng.normal(0, 3.0), 1, 1.0 + 3 * warm
                    )
                )

        # move vehicle and boat over dt
        vn = speed * math.cos(math.radians(heading)) + cn
        ve = speed * math.sin(math.radians(heading)) + ce
        lat, lon = _offset(lat, lon, vn * dt, ve * dt)
        if b.wander_mps > 0:
            boat_course += rng.normal(0.0, b.course_wander_deg_per_sqrt_s * math.sqrt(dt))
        bvn = b.speed_mps * math.cos(math.radians(boat_course))
        bve = b.speed_mps * math.sin(math.radians(boat_course))
        if b.drifts_with_current:
            bvn += cn
            bve += ce
        bvn += rng.normal(0.0, b.wander_mps)
        bve += rng.normal(0.0, b.wander_mps)
        boat_lat, boat_lon = _offset(boat_lat, boat_lon, bvn * dt, bve * dt)

    channel = AcousticChannel(sc, rng, truth, boat_gps, transducer, dt)
    fixed, overrides = _transponders(sc, rng)
    pings, replies, acoustic = _acoustics(channel, fixed)
    records.extend(acoustic)
    records.sort(key=lambda r: r.t)  # stable: sensor order within an instant is kept
    return Mission(sc, seed, truth, records, pings, replies, channel, overrides)


def _transponders(
    sc: Scenario, rng: np.random.Generator
) -> tuple[list[tuple[Any, np.ndarray]], dict[str, Any]]:
    """True ECEF positions of fixed transponders, and the surveyed ones the crew configures."""
    fixed, beacons = [], {}
    for tp in sc.acoustics.transponders:
        lat, lon = _offset(sc.vehicle.lat, sc.vehicle.lon, tp.north_m, tp.east_m)
        fixed.append((tp, _ecef(lat, lon, sc.surface_altitude_m - tp.depth_m)))
        slat, slon = _offset(lat, lon, *rng.normal(0.0, tp.survey_std_m, 2))
        beacons[tp.name] = {
            "lat": slat,
            "lon": slon,
            "depth": tp.depth_m,
            "turnaround_s": tp.turnaround_s,
            "position_std_m": tp.survey_std_m,
        }
    return fixed, ({"beacons": beacons} if beacons else {})


class AcousticChannel:
    """The acoustic link between the vehicle's modem and the deck box's transducer.

    ``ping(t_ping)`` answers what the modem would print for a ping sent at ``t_ping``:
    a :class:`Range` stamped with the arrival of the reply, or None when the ping is
    lost.  It uses the precomputed truth, so the offline simulator and the real-time
    modem emulator hear the same channel.  The deck box reports the position its GPS
    gave at the last whole second (the shore laptop updates it at 1 Hz over COM1).
    """

    def __init__(
        self,
        sc: Scenario,
        rng: np.random.Generator,
        truth: list[TruthSample],
        boat_gps: list[tuple[float, float]],
        transducer: list[tuple[float, float]],
        dt: float,
    ) -> None:
        a = sc.acoustics
        self.sc, self.a, self.rng = sc, a, rng
        self.truth, self.boat_gps, self.transducer, self.dt = truth, boat_gps, transducer, dt
        self.h0 = sc.surface_altitude_m
        self.c_water = coppens(
            a.temperature_c, a.salinity_ppt, 0.5 * (sc.vehicle.depth_m + sc.boat.transducer_depth_m)
        )
        # Gilbert-Elliott drops: bad state entered with p_gb, left with p_bg = 1/burst.
        self.p_bg = 1.0 / a.drop_burst_pings
        frac = min(a.drop_prob, 0.95)
        self.p_gb = frac * self.p_bg / max(1e-9, 1.0 - frac)
        self.bad = False
        self.t_end = (len(truth) - 1) * dt
        # replies an ideal outlier detector keeps (no multipath, the position as sent),
        # as (arrival, beacon): what the bench's Cramer-Rao bound is computed from
        self.clean: list[tuple[float, str]] = []
        # spans with no location line from the boat: replies carry no position
        self.outages: list[tuple[float, float]] = []
        for _ in range(a.location_outages):
            span = float(rng.uniform(a.location_outage_min_s, a.location_outage_max_s))
            start = float(rng.uniform(0.0, max(0.0, self.t_end - span)))
            self.outages.append((start, start + span))

    def _index(self, t: float) -> tuple[int, float]:
        i = min(len(self.truth) - 2, max(0, int(t / self.dt)))
        return i, (t - i * self.dt) / self.dt

    def vehicle_at(self, t: float) -> np.ndarray:
        i, w = self._index(t)
        p0, p1 = self.truth[i], self.truth[i + 1]
        return (1 - w) * _ecef(p0.lat, p0.lon, self.h0 - p0.depth) + w * _ecef(
            p1.lat, p1.lon, self.h0 - p1.depth
        )

    def transducer_at(self, t: float) -> np.ndarray:
        i, w = self._index(t)
        (la0, lo0), (la1, lo1) = self.transducer[i], self.transducer[i + 1]
        hd = self.h0 - self.sc.boat.transducer_depth_m
        return (1 - w) * _ecef(la0, lo0, hd) + w * _ecef(la1, lo1, hd)

    def _round_trip(
        self, t_ping: float, target_at: Callable[[float], np.ndarray], turnaround: float
    ) -> tuple[float, float]:
        """Times the target hears the ping and the vehicle hears the reply (fixed points)."""
        c = self.c_water
        pv = self.vehicle_at(t_ping)
        tb = t_ping
        for _ in range(4):  # out leg: the beacon hears the ping at tb
            tb = t_ping + float(np.linalg.norm(target_at(tb) - pv)) / c
        pb = target_at(tb)
        tr = tb + turnaround
        for _ in range(4):  # back leg: the vehicle hears the reply at tr
            tr = tb + turnaround + float(np.linalg.norm(self.vehicle_at(tr) - pb)) / c
        return tb, tr

    def _lost(self) -> bool:
        rng = self.rng
        self.bad = (rng.random() >= self.p_bg) if self.bad else (rng.random() < self.p_gb)
        return self.bad

    def ping_transponder(self, t_ping: float, tp: Any, where: np.ndarray) -> TravelTime | None:
        """One interrogation of a fixed transponder: the raw round-trip travel time."""
        a, rng = self.a, self.rng
        if self._lost():
            return None
        _, tr = self._round_trip(t_ping, lambda _t: where, tp.turnaround_s)
        if tr - t_ping > a.timeout_s:
            return None
        extra = rng.normal(0.0, a.range_noise_m)
        if rng.random() < a.multipath_prob:
            extra += self._multipath()
        twtt = tr - t_ping + 2.0 * extra / self.c_water
        if abs(extra) < 5.0 * a.range_noise_m + 1e-9:
            self.clean.append((round(tr, 6), tp.name))
        return TravelTime(round(tr, 6), round(t_ping, 6), round(max(0.0, twtt), 9), tp.name)

    def _multipath(self) -> float:
        """How much longer a multipath reply reads than the direct path."""
        a = self.a
        if a.multipath_max_m > 0.0:
            return float(self.rng.uniform(a.multipath_min_m, a.multipath_max_m))
        return float(self.rng.exponential(a.multipath_mean_m))

    def ping(self, t_ping: float) -> Range | None:
        a, rng = self.a, self.rng
        if self._lost():
            return None
        tb, tr = self._round_trip(t_ping, self.transducer_at, a.turnaround_s)
        if tr - t_ping > a.timeout_s:
            return None
        m = a.modem_mps * (tr - t_ping - a.turnaround_s) / 2.0
        m += rng.normal(0.0, a.range_noise_m)
        multipath = rng.random() < a.multipath_prob
        if multipath:
            m += self._multipath()
        i = min(len(self.boat_gps) - 1, int(math.floor(tb)) * round(1.0 / self.dt))
        blat, blon = self.boat_gps[i]
        bdepth: float | None = self.sc.boat.transducer_depth_m
        if rng.random() < a.corrupt_position_prob:
            kind = rng.integers(3)
            if kind == 0:  # a garbled digit: hundreds of metres to kilometres off
                blat += float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.05))
            elif kind == 1:
                blon += float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.05))
            else:  # the position field missing from the reply
                blat = blon = None  # type: ignore[assignment]
                bdepth = None
        corrupt = blat != self.boat_gps[i][0] or blon != self.boat_gps[i][1]
        if a.corrupt_gross_prob and blat is not None and rng.random() < a.corrupt_gross_prob:
            corrupt = True
            if rng.random() < 0.5:
                blat = max(
                    -89.0, min(89.0, blat + float(rng.choice([-1, 1]) * rng.uniform(0.1, 5.0)))
                )
            else:
                blon = 0.0
        if any(t0 <= tr < t1 for t0, t1 in self.outages):
            blat = blon = None  # type: ignore[assignment]
            bdepth = None
        elif not (multipath or corrupt):
            self.clean.append((round(tr, 6), "udb"))
        return Range(
            round(tr, 6),
            round(t_ping, 6),
            round(max(0.0, m), 3),
            "udb",
            blat,
            None if blon is None else _wrap_deg(blon),
            bdepth,
        )


def _acoustics(
    channel: AcousticChannel, fixed: list[tuple[Any, np.ndarray]]
) -> tuple[int, int, list[Record]]:
    """Ping every ``ping_interval_s``: the boat's UDB, or the transponders round robin."""
    a = channel.a
    out: list[Record] = []
    pings = 0
    t_ping = a.ping_interval_s
    while t_ping < channel.t_end - a.timeout_s:
        if fixed:
            tp, where = fixed[pings % len(fixed)]
            r: Record | None = channel.ping_transponder(t_ping, tp, where)
        else:
            r = channel.ping(t_ping)
        pings += 1
        if r is not None:
            out.append(r)
        t_ping += a.ping_interval_s
    return pings, len(out), out
