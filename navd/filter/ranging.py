"""What one acoustic range becomes: the beacon's position for it, the range at the
water's sound speed, the virtual-LBL net it also goes to, the filter's gate, and the
decision that is published for it (whatever happened, every range gets one)."""

from __future__ import annotations

import math
from collections import Counter
from functools import partial

import numpy as np

from navd.acoustics import slant_range
from navd.filter.advisory import Observability
from navd.filter.beacons import BeaconFix, BeaconResolver
from navd.filter.common import NavFilter, RangeMeas
from navd.filter.deadreckoning import DeadReckoner
from navd.filter.integrity import Integrity
from navd.filter.vlbl import NetRange, VirtualNet
from navd.records import Range, TravelTime
from navd.schema import RangeDecision
from navd.settings import Config


class Ranging:
    def __init__(self, cfg: Config, counters: Counter[str]) -> None:
        self.nav = cfg.navigation
        self.counters = counters
        self.beacons = BeaconResolver(cfg.beacons, self.nav.gate)
        self.sound = self.nav.sound_speed.model_obj()
        self.net = VirtualNet()
        self.observability = Observability()

    def decide(
        self,
        rec: Range | TravelTime,
        flt: NavFilter,
        integrity: Integrity,
        dr: DeadReckoner,
        *,
        depth_m: float,
        surface_alt: float,
        gps_fresh: bool,
        gps_seen: bool,
    ) -> RangeDecision:
        """Fuse one range if it can be; ``gps_fresh``: a fix is fresh at its time,
        ``gps_seen``: there has been a fix since the filter started."""
        fix, why = self.beacons.resolve(
            rec.t, rec.beacon, rec.beacon_lat, rec.beacon_lon, rec.beacon_depth
        )
        if fix is None:
            return self._refused(RangeDecision(rec.t, rec.t_ping, rec.beacon, reason=why))
        if fix.predicted_s > 0.0:
            self.counters["ranges_beacon_predicted"] += 1
        c_water = self.sound.at(0.5 * (depth_m + fix.depth))
        rng = slant_range(
            rec, c_water, self.sound.modem_mps, fix.turnaround_s, flt.ranges_as_reported
        )
        placed = partial(
            RangeDecision,
            rec.t,
            rec.t_ping,
            rec.beacon,
            beacon_lat=math.degrees(fix.lat),
            beacon_lon=math.degrees(fix.lon),
            beacon_depth=fix.depth,
            beacon_predicted_s=fix.predicted_s if fix.predicted_s > 0.0 else None,
            range_m=rng,
        )
        if not 0.0 < rng <= self.nav.gate.max_range_m:
            return self._refused(placed(reason="range_out_of_bounds"))
        self._to_net(rec.t, fix, rng, flt, dr, depth_m, surface_alt, gps_seen)
        if not flt.initialised:
            return self._refused(placed(reason="not_initialised"))
        if flt.ranges_only_without_gps and gps_fresh:
            return self._refused(placed(reason="gps_available"))
        meas = RangeMeas(
            t=rec.t,
            t_ping=rec.t_ping,
            range_m=rng,
            beacon=rec.beacon,
            beacon_lat=fix.lat,
            beacon_lon=fix.lon,
            beacon_hd=surface_alt - fix.depth,
            vehicle_hd=surface_alt - depth_m,
            # a predicted beacon's error is in the range's noise, and named apart: it is
            # shared by the outage's replies, and the filter estimating this beacon's
            # position error takes it into those states
            std_m=math.hypot(self.nav.noise.range_std_m, fix.predicted_std_m),
            beacon_position_std_m=fix.position_std_m,
            beacon_position_corr_s=fix.position_corr_s,
            beacon_predicted_std_m=fix.predicted_std_m,
            beacon_predicted_from=fix.predicted_from,
        )
        d = flt.range_update(meas)
        # refused on its residual as reading short: not multipath, which only lengthens
        short = d.on_residual and d.residual_m < 0.0
        integrity.range(d.accepted, flt.last_nis, short, flt.last_pull)
        self.counters["ranges_accepted" if d.accepted else "ranges_rejected"] += 1
        if d.accepted:
            est = flt.estimate()
            self.observability.add(
                rec.t,
                math.degrees(est.lat),
                math.degrees(est.lon),
                math.degrees(fix.lat),
                math.degrees(fix.lon),
                math.hypot(meas.std_m, fix.position_std_m),
            )
        else:
            self.counters[f"range_{d.reason}"] += 1
        return placed(
            accepted=d.accepted,
            residual_m=d.residual_m if math.isfinite(d.residual_m) else None,
            gate_m=d.gate_m if math.isfinite(d.gate_m) else None,  # None: no gate (vlbl)
            reason=d.reason,
            nis=flt.last_nis if math.isfinite(flt.last_nis) else None,
        )

    def _refused(self, decision: RangeDecision) -> RangeDecision:
        """A range that never reached the filter's gate, counted by why."""
        self.counters[f"range_{decision.reason}"] += 1
        self.counters["ranges_rejected"] += 1
        return decision

    def _to_net(
        self,
        t: float,
        fix: BeaconFix,
        rng: float,
        flt: NavFilter,
        dr: DeadReckoner,
        depth_m: float,
        h: float,
        gps_seen: bool,
    ) -> None:
        """Every usable range also goes to the virtual LBL net (seed 001 / 004 fix)."""
        std = math.hypot(self.nav.noise.range_std_m, fix.position_std_m, fix.predicted_std_m)
        r = NetRange(t, fix.lat, fix.lon, h - fix.depth, rng, std, self.net.rel_n, self.net.rel_e)
        guess = None
        if flt.initialised:
            est = flt.estimate()
            guess = (est.lat, est.lon)
        lsfix = self.net.add(r, h - depth_m, guess)
        if lsfix is not None and flt.initialised:
            flt.apply_fix(lsfix)
        if lsfix is not None and not flt.initialised and not gps_seen:
            # no GPS yet: the acoustic fix initialises the filter (seed 004, section III)
            std0 = math.sqrt(max(0.0, float(np.linalg.eigvalsh(lsfix.cov_ne)[-1])))
            flt.initialise(lsfix.lat, lsfix.lon, max(std0, 1.0), t)
            dr.reset(lsfix.lat, lsfix.lon)
            self.counters["initialised_from_acoustic_fix"] += 1
