"""An NMEA 0183 GPS receiver as real ones talk: GGA and RMC once a second, and around them
what nobody asked for.

The manual's receiver sends GGA and RMC.  Real receivers (gpsd's regression captures,
tests/data/gpsd) also send GSA, GSV, VTG and ZDA, a vendor's proprietary ``$P...``
sentence, one GGA per constellation for the same epoch (GP then GL), and close lines
with CR LF, LF or CR alone.  ``chatter=False`` and ``second_talker=None`` give the
manual's receiver.
"""

from __future__ import annotations

import datetime as dt
from functools import reduce
from pathlib import Path

from navd.hil.emulators.base import Emulator


def sentence(body: str, end: bytes = b"\r\n") -> bytes:
    cs = reduce(lambda a, c: a ^ ord(c), body, 0)
    return f"${body}*{cs:02X}".encode("ascii") + end


def _dm(value: float, is_lat: bool) -> tuple[str, str]:
    hemi = ("N" if value >= 0 else "S") if is_lat else ("E" if value >= 0 else "W")
    v = abs(value)
    deg = int(v)
    minutes = (v - deg) * 60.0
    return (f"{deg:02d}{minutes:09.6f}" if is_lat else f"{deg:03d}{minutes:09.6f}"), hemi


class GpsEmulator(Emulator):
    def __init__(
        self,
        path: str | Path,
        seed: int = 0,
        rate_hz: float = 1.0,
        baudrate: int | None = None,
        line_end: bytes = b"\r\n",
        second_talker: str | None = "GL",
        chatter: bool = True,
    ) -> None:
        super().__init__(path, seed, baudrate)
        self.line_end = line_end
        self.second_talker = second_talker
        self.chatter = chatter
        # a receiver's glitch: the next fix this many times at (0, 0), checksum and all
        self.glitches = 0
        self.lat: float | None = None  # None: no fix
        self.lon: float | None = None
        self.alt_msl = 0.0
        self.geoid_sep = 0.0
        self.hdop = 1.0
        self.utc = dt.datetime(2016, 1, 8, 15, 4, 5, tzinfo=dt.UTC)
        self.rate_hz = rate_hz

    def start(self) -> None:
        self.every(1.0 / self.rate_hz, self._tick)

    def gga(self, talker: str = "GP") -> bytes:
        hms = self.utc.strftime("%H%M%S.00")
        if self.lat is None or self.lon is None:
            return sentence(f"{talker}GGA,{hms},,,,,0,00,99.9,,M,,M,,", self.line_end)
        la, ns = _dm(self.lat, True)
        lo, ew = _dm(self.lon, False)
        if self.glitches > 0 and talker == "GP":
            self.glitches -= 1
            la, ns, lo, ew = "0000.000000", "N", "00000.000000", "E"
        return sentence(
            f"{talker}GGA,{hms},{la},{ns},{lo},{ew},1,08,{self.hdop:.1f},"
            f"{self.alt_msl:.1f},M,{self.geoid_sep:.1f},M,,",
            self.line_end,
        )

    def rmc(self) -> bytes:
        hms = self.utc.strftime("%H%M%S.00")
        dmy = self.utc.strftime("%d%m%y")
        if self.lat is None or self.lon is None:
            return sentence(f"GPRMC,{hms},V,,,,,,,{dmy},,,N", self.line_end)
        la, ns = _dm(self.lat, True)
        lo, ew = _dm(self.lon, False)
        return sentence(f"GPRMC,{hms},A,{la},{ns},{lo},{ew},0.0,0.0,{dmy},,,A", self.line_end)

    def unasked(self) -> list[bytes]:
        """What a real receiver adds each epoch (shapes of the captures in tests/data/gpsd)."""
        hms = self.utc.strftime("%H%M%S.00")
        e = self.line_end
        return [
            sentence("GPGSA,A,3,04,05,09,12,17,24,25,29,,,,,1.8,1.0,1.5", e),
            sentence("GPGSV,2,1,08,04,41,265,38,05,19,044,33,09,25,303,31,12,53,098,40", e),
            sentence("GPGSV,2,2,08,17,16,196,29,24,69,317,44,25,33,131,36,29,11,064,25", e),
            sentence("GPVTG,0.0,T,,M,0.0,N,0.0,K,A", e),
            sentence(self.utc.strftime(f"GPZDA,{hms},%d,%m,%Y,00,00"), e),
            sentence(f"PGLOR,1,STA,{hms},0.000,0.000,-100,0,0,0,P,F,L,1,C,0,S,0000", e),
        ]

    def epoch(self) -> list[bytes]:
        """One epoch's sentences, in the order receivers send them."""
        out = [self.gga()]
        if self.second_talker:
            out.append(self.gga(self.second_talker))
        out.append(self.rmc())
        if self.chatter:
            out += self.unasked()
        return out

    def _tick(self) -> None:
        self.utc += dt.timedelta(seconds=1.0 / self.rate_hz)
        for s in self.epoch():
            self.send(s)
