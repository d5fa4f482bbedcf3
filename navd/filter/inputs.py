"""The inputs the filter is driven by between measurements: heading and RPM, held from
their last sample (zero-order hold), and the speed through the water they give."""

from __future__ import annotations

import math

from navd.filter import compass
from navd.records import Attitude, Heading, Rpm
from navd.settings import NavigationConfig


class HeldInputs:
    def __init__(self, nav: NavigationConfig) -> None:
        self.speed = nav.speed
        self.stale_s = nav.stale_input_s
        self.decl = math.radians(nav.magnetic_declination_deg)
        self.deviation = tuple(nav.compass_deviation_deg)
        self.heading_deg: float | None = None  # magnetic, deviation removed
        self.t_heading = -math.inf
        self.rpm: float | None = None
        self.t_rpm = -math.inf

    def heading(self, rec: Heading) -> None:
        self.heading_deg, self.t_heading = compass.correct(self.deviation, rec.deg), rec.t

    def attitude(self, rec: Attitude) -> float:
        """Hold the attitude's yaw as the heading; returns it, deviation removed."""
        yaw = compass.correct(self.deviation, rec.yaw_deg)
        self.heading_deg, self.t_heading = yaw, rec.t
        return yaw

    def motor(self, rec: Rpm) -> None:
        self.rpm, self.t_rpm = rec.rpm, rec.t

    def heading_speed(self) -> tuple[float, float]:
        """True heading (radians) and water speed (m/s) from the RPM map."""
        if self.heading_deg is None:
            return 0.0, 0.0  # no compass yet: hold position rather than guess a direction
        sp = self.speed
        rpm = self.rpm or 0.0
        speed = rpm / sp.rpm_per_mps
        if rpm > 0:  # ahead: the trial's offset, never a speed astern
            speed = max(0.0, speed + sp.offset_mps)
        return math.radians(self.heading_deg) + self.decl, speed

    def stale(self, t: float) -> list[str]:
        """The inputs older than ``navigation.stale_input_s`` at ``t``."""
        out = []
        if t - self.t_heading > self.stale_s:
            out.append("heading")
        if t - self.t_rpm > self.stale_s:
            out.append("rpm")
        return out
