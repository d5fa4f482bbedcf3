"""The navigator's restart while submerged (navd/daemon/checkpoint.py keeps the file):
what a checkpoint holds, and navigating on from one."""

from __future__ import annotations

import math

import numpy as np

from navd.filter.common import Held
from navd.filter.navparts import NavParts
from navd.records import Resume


class Resuming(NavParts):
    def snapshot(self) -> dict[str, object] | None:
        """What a restart needs to resume navigating (None: nothing to resume yet): the
        filter's state and covariance, the ranges' scale as learnt, the depth gauge's zero,
        the water's height, the tracked beacon's outage under way, how often replies read
        long."""
        f = self.filter
        if not f.initialised:
            return None
        x, P, held = f.checkpoint()
        snap: dict[str, object] = {
            "mode": self.cfg.navigation.filter,
            "x": x.tolist(),
            "P": P.ravel().tolist(),
            "surface_bar": self.depth.zero_bar,
            "surface_alt": self.surface_altitude,
            "depth_m": self.depth.m,
            "lat": math.degrees(float(x[0])),
            "lon": math.degrees(float(x[1])),
        }
        if held.scale is not None:
            snap["range_scale"], snap["range_scale_var"] = held.scale
        if held.outage is not None:
            snap["beacon_outage"] = list(held.outage)
        if held.long_refused is not None:
            snap["long_refused"] = list(held.long_refused)
        if held.range_noise is not None:
            snap["range_noise"] = list(held.range_noise)
        return snap

    def _on_resume(self, rec: Resume) -> None:
        """Navigate on from a checkpoint: navd restarted (a crash, the watchdog) while
        the vehicle was away from GPS.  Its position covariance grows with the time
        the daemon was down, and integrity is degraded until ranges confirm it."""
        n = len(rec.x)
        # a new process: what the one before knew is gone (a replay of its log goes on
        # from here as the daemon did)
        self._fresh()
        if rec.mode != self.cfg.navigation.filter or n != len(np.asarray(self.filter.x)):
            self.counters["resume_refused_mode"] += 1
            return
        if len(rec.P) != n * n:
            self.counters["resume_refused_covariance"] += 1
            return
        x = np.array(rec.x, dtype=float)
        P = np.array(rec.P, dtype=float).reshape(n, n)
        if not np.all(np.linalg.eigvalsh(0.5 * (P + P.T)) >= -1e-9):
            self.counters["resume_refused_covariance"] += 1
            return
        grow = (self.cfg.checkpoint.drift_mps * rec.age_s) ** 2
        self.filter.initialise(float(x[0]), float(x[1]), 1.0, rec.t)
        scale = None
        if rec.range_scale is not None and rec.range_scale_var is not None:
            scale = (rec.range_scale, rec.range_scale_var)
        self.filter.restore(
            x, P, grow, Held(scale, rec.beacon_outage, rec.long_refused, rec.range_noise)
        )
        self._t_filter = rec.t
        self.dr.reset(float(x[0]), float(x[1]))
        if rec.surface_bar is not None:
            self.depth.zero_at(rec.surface_bar)
        if rec.surface_alt is not None:
            self.gps.seed_altitude(rec.surface_alt)
        if rec.depth_m is not None:
            self.depth.depth(rec.t, rec.depth_m)
        self.integrity.resumed(
            f"resumed from a checkpoint {rec.age_s:.0f} s old, not yet confirmed by ranges"
        )
        self.counters["resumed"] += 1
