"""An NMEA 0183 GPS receiver: GGA and RMC once a second, empty fields without a fix."""

from __future__ import annotations

import datetime as dt
from functools import reduce

from navd.hil.emulators.base import Emulator


def sentence(body: str) -> bytes:
    cs = reduce(lambda a, c: a ^ ord(c), body, 0)
    return f"${body}*{cs:02X}\r\n".encode("ascii")


def _dm(value: float, is_lat: bool) -> tuple[str, str]:
    hemi = ("N" if value >= 0 else "S") if is_lat else ("E" if value >= 0 else "W")
    v = abs(value)
    deg = int(v)
    minutes = (v - deg) * 60.0
    return (f"{deg:02d}{minutes:09.6f}" if is_lat else f"{deg:03d}{minutes:09.6f}"), hemi


class GpsEmulator(Emulator):
    def __init__(
        self, path, seed: int = 0, rate_hz: float = 1.0, baudrate: int | None = None
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.lat: float | None = None  # None: no fix
        self.lon: float | None = None
        self.alt_msl = 0.0
        self.geoid_sep = 0.0
        self.hdop = 1.0
        self.utc = dt.datetime(2016, 1, 8, 15, 4, 5, tzinfo=dt.UTC)
        self.rate_hz = rate_hz

    def start(self) -> None:
        self.every(1.0 / self.rate_hz, self._tick)

    def gga(self) -> bytes:
        hms = self.utc.strftime("%H%M%S.00")
        if self.lat is None or self.lon is None:
            return sentence(f"GPGGA,{hms},,,,,0,00,99.9,,M,,M,,")
        la, ns = _dm(self.lat, True)
        lo, ew = _dm(self.lon, False)
        return sentence(
            f"GPGGA,{hms},{la},{ns},{lo},{ew},1,08,{self.hdop:.1f},"
            f"{self.alt_msl:.1f},M,{self.geoid_sep:.1f},M,,"
        )

    def rmc(self) -> bytes:
        hms = self.utc.strftime("%H%M%S.00")
        dmy = self.utc.strftime("%d%m%y")
        if self.lat is None or self.lon is None:
            return sentence(f"GPRMC,{hms},V,,,,,,,{dmy},,,N")
        la, ns = _dm(self.lat, True)
        lo, ew = _dm(self.lon, False)
        return sentence(f"GPRMC,{hms},A,{la},{ns},{lo},{ew},0.0,0.0,{dmy},,,A")

    def _tick(self) -> None:
        self.utc += dt.timedelta(seconds=1.0 / self.rate_hz)
        self.send(self.gga())
        self.send(self.rmc())
