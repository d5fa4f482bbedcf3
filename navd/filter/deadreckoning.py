"""The one dead reckoner: a geodetic track moved by what the vehicle says of its own motion.

Compass heading and RPM speed move it along the geodesic (the uncorrected track the
thesis plots in magenta, seed 000 Figures 4.6-4.19); a DVL's north and east velocity
moves it by an offset (navd/filter/dvl.py).  No current: it is reset at every fix.
"""

from __future__ import annotations

from navd import geodesy


class DeadReckoner:
    def __init__(self) -> None:
        self.lat: float | None = None
        self.lon: float | None = None

    def reset(self, lat: float, lon: float) -> None:
        self.lat, self.lon = lat, lon

    def step(self, dt: float, heading: float, speed: float, hd: float) -> None:
        """``speed`` m/s for ``dt`` s along ``heading`` (radians from true north)."""
        if self.lat is None or self.lon is None:
            return
        d = speed * dt
        if d != 0.0:
            self.lat, self.lon, _ = geodesy.destination(self.lat, self.lon, heading, d, hd)

    def move(self, dn: float, de: float, hd: float) -> None:
        """``dn`` m north and ``de`` m east (a velocity over a short interval)."""
        if self.lat is None or self.lon is None:
            return
        self.lat, self.lon = geodesy.offset_position(self.lat, self.lon, dn, de, hd)
