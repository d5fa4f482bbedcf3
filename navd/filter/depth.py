"""Depth below the surface: as a sensor gives it, or from absolute pressure.

Absolute pressure is zeroed by the median of the pressures read while GPS had a fix
(the antenna was out of the water): weather and the sensor's own offset are measured
before every dive, so no zeroing is ever written into the sensor.
"""

from __future__ import annotations

import math
import statistics
from collections import deque

from navd.settings import SiteConfig

SURFACE_SAMPLES = 50  # the median of the last this many surface pressures is the zero


class DepthGauge:
    def __init__(self, site: SiteConfig) -> None:
        self.site = site
        self.m = 0.0  # depth, positive down
        self.t = -math.inf  # when it was last measured
        self._p_surface: deque[float] = deque(maxlen=SURFACE_SAMPLES)

    @property
    def zero_bar(self) -> float | None:
        """The surface pressure depth is measured from, if readings at the surface gave it."""
        return statistics.median(self._p_surface) if self._p_surface else None

    def zero_at(self, bar: float) -> None:
        """The surface pressure of before a restart (the vehicle is submerged now)."""
        self._p_surface.clear()
        self._p_surface.append(bar)

    def depth(self, t: float, m: float) -> None:
        self.m, self.t = m, t

    def pressure(self, t: float, bar: float, surfaced: bool) -> None:
        """Absolute pressure; ``surfaced``: GPS has a fix, so this is the surface's."""
        site = self.site
        if site.surface_pressure_from_gps and surfaced:
            self._p_surface.append(bar)
        p0 = statistics.median(self._p_surface) if self._p_surface else site.surface_pressure_bar
        self.m = (bar - p0) * 1e5 / (site.water_density_kgm3 * site.gravity_mps2)
        self.t = t
