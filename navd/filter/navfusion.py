"""The navigator's measurements of position (navd/filter/navparts.py): a GPS fix, gated
against the estimate and able to restart it, and a range, which navd/filter/ranging.py
turns into a decision."""

from __future__ import annotations

import math

from navd.filter.navparts import NavParts
from navd.records import Gps, Range, TravelTime
from navd.schema import RangeDecision


class Fusion(NavParts):
    def _on_gps(self, rec: Gps) -> None:
        std, said = self.gps.judge(rec, self._at_surface(), self.depth.t)
        for c in said:
            self.counters[c] += 1
        if std is None or rec.lat is None or rec.lon is None:
            return
        lat, lon = math.radians(rec.lat), math.radians(rec.lon)
        hd = self.surface_altitude - self.depth.m
        if self.filter.initialised:
            # the first fix of a mission, and the first after a reset, are not gated
            verdict = self.gps_gate.judge(self.filter.estimate(), lat, lon, std, rec.t)
            if verdict == "refuse":
                self.counters["gps_refused_gate"] += 1
                self.integrity.fix_refused()
                return
            if verdict == "take":
                # several fixes agree with each other and not with the estimate: it had
                # drifted beyond its covariance, and they are the position
                self.counters["gps_reacquired"] += 1
                self.restart("gps_disagrees")
                self.gps.t_last = rec.t  # this fix counts: it is the one restarting it
        if not self.filter.initialised:
            self.filter.initialise(lat, lon, std, rec.t)
            self._t_filter = rec.t
        else:
            self.filter.gps_update(lat, lon, std, hd)
        self.integrity.clear()
        self.dr.reset(lat, lon)
        self.dvl.reset(lat, lon, rec.t)
        self.counters["gps_fused"] += 1

    def _on_range(self, rec: Range | TravelTime) -> RangeDecision:
        return self.ranging.decide(
            rec,
            self.filter,
            self.integrity,
            self.dr,
            depth_m=self.depth.m,
            surface_alt=self.surface_altitude,
            gps_fresh=self.gps.fresh(rec.t),
            gps_seen=self.gps.t_last is not None,
        )
