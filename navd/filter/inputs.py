"""The inputs the filter is driven by between measurements: heading and RPM, held from
their last sample (zero-order hold), and the speed through the water they give.

Between two filter steps the inputs may change several times (the AHRS at 20 Hz, the
RPM and the pressure at 10 Hz, none of them on the tick).  Rather than stepping the
filter to every change, the step takes the time-weighted mean of the held velocity
over it: the position it moves by is the same sum of held velocities times their
durations, and the Jacobians, linear in that velocity, are the same to first order.
A step with one held value uses that value as it is."""

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
        # what was held since the step that began at _t0: (heading, speed, seconds)
        self._t0 = math.nan
        self._t = math.nan
        self._held: list[tuple[float, float, float]] = []

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

    def carry(self, t0: float, t: float) -> None:
        """Remember the value held from the last change (or ``t0``, the step's start)
        until ``t``, where it is about to change."""
        if self._t0 != t0:
            self._t0 = self._t = t0
            self._held.clear()
        dt = t - self._t
        if dt <= 0.0:
            return
        h, s = self.heading_speed()
        if self._held and self._held[-1][:2] == (h, s):
            self._held[-1] = (h, s, self._held[-1][2] + dt)
        else:
            self._held.append((h, s, dt))
        self._t = t

    def over(self, t0: float, t: float) -> tuple[float, float]:
        """Heading and speed for the step from ``t0`` to ``t``: the held velocity's
        time-weighted mean (see the module's text)."""
        if self._t0 != t0:
            return self.heading_speed()  # nothing changed since the step began
        self.carry(t0, t)
        self._t0 = math.nan
        held, self._held = self._held, []
        if len(held) == 1:
            return held[0][0], held[0][1]
        if not held:
            return self.heading_speed()
        n = e = total = 0.0
        for h, s, dt in held:
            n += s * math.cos(h) * dt
            e += s * math.sin(h) * dt
            total += dt
        speed = math.hypot(n, e) / total
        return (math.atan2(e, n) if speed > 0.0 else self.heading_speed()[0]), speed

    def stale(self, t: float) -> list[str]:
        """The inputs older than ``navigation.stale_input_s`` at ``t``."""
        out = []
        if t - self.t_heading > self.stale_s:
            out.append("heading")
        if t - self.t_rpm > self.stale_s:
            out.append("rpm")
        return out
