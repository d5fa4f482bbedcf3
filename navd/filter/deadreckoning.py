"""Dead reckoning alongside the filter: compass heading and RPM speed, no current, reset by GPS."""

from __future__ import annotations

from navd import geodesy


class DeadReckoner:
    """The uncorrected geodetic track the thesis plots in magenta (seed 000 Figures 4.6-4.19)."""

    def __init__(self) -> None:
        self.lat: float | None = None
        self.lon: float | None = None

    def reset(self, lat: float, lon: float) -> None:
        self.lat, self.lon = lat, lon

    def step(self, dt: float, heading: float, speed: float, hd: float) -> None:
        if self.lat is None or self.lon is None:
            return
        d = speed * dt
        if d != 0.0:
            self.lat, self.lon, _ = geodesy.destination(self.lat, self.lon, heading, d, hd)
