"""GPS receiver (Linx RXM-GPS-R4 and any NMEA 0183 receiver): GGA and RMC, sans-I/O.

Sentences are ``$<talker><type>,...*hh<CR><LF>`` (NMEA 0183 v3, docs/protocols.md);
pynmea2 parses them.  GGA gives the fix: quality 0 none, 1 GPS, 2 DGPS (others count
as GPS), altitude above mean sea level plus the geoid separation, which makes the
ellipsoidal height the filter wants.  Empty fields before a fix give a ``fix 0``
record.  RMC gives UTC date and time and the receiver's validity flag.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import pynmea2

from drivers.codec import DecodeStats
from navd.records import Gps

_MAX_LINE = 120  # NMEA allows 82 characters; anything much longer is garbage


@dataclass(frozen=True, slots=True)
class GpsTime:
    t: float
    utc: dt.datetime | None
    valid: bool


def _f(s: str) -> float | None:
    try:
        return float(s) if s else None
    except ValueError:
        return None


class NmeaDecoder:
    def __init__(self) -> None:
        self.stats = DecodeStats()
        self._buf = bytearray()

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        self._buf += data
        out: list[object] = []
        while True:
            start = self._buf.find(b"$")
            if start < 0:
                if self._buf:
                    self.stats.skip(len(self._buf), "no_start")
                    self._buf.clear()
                break
            if start:
                self.stats.skip(start, "no_start")
                del self._buf[:start]
            end = self._buf.find(b"\n")
            nxt = self._buf.find(b"$", 1)
            if nxt > 0 and (end < 0 or nxt < end):
                # a sentence cut short by the next one
                self.stats.skip(nxt, "truncated")
                self.stats.bad_frame += 1
                del self._buf[:nxt]
                continue
            if end < 0:
                if len(self._buf) > _MAX_LINE:
                    self.stats.skip(len(self._buf), "too_long")
                    self.stats.bad_frame += 1
                    self._buf.clear()
                break
            line = bytes(self._buf[: end + 1])
            del self._buf[: end + 1]
            rec = self._sentence(line, t)
            if rec is not None:
                out.append(rec)
                self.stats.records += 1
        return out

    def _sentence(self, line: bytes, t: float) -> object | None:
        try:
            text = line.decode("ascii").strip()
            msg = pynmea2.parse(text, check=True)
        except pynmea2.ChecksumError:
            self.stats.bad_checksum += 1
            self.stats.skip(len(line), "checksum")
            return None
        except (UnicodeDecodeError, pynmea2.ParseError, ValueError, AttributeError):
            self.stats.bad_frame += 1
            self.stats.skip(len(line), "unparseable")
            return None
        if "*" not in text:
            self.stats.bad_checksum += 1  # a sentence without its checksum is not trusted
            self.stats.skip(len(line), "no_checksum")
            return None
        kind = msg.sentence_type
        try:
            if kind == "GGA":
                return self._gga(msg, t)
            if kind == "RMC":
                return self._rmc(msg, t)
        except (ValueError, TypeError, AttributeError):
            self.stats.bad_frame += 1
            self.stats.skip(len(line), "bad_fields")
            return None
        self.stats.reasons["ignored_" + kind] = self.stats.reasons.get("ignored_" + kind, 0) + 1
        return None

    def _gga(self, msg: pynmea2.GGA, t: float) -> Gps:
        quality = int(msg.gps_qual or 0)
        hdop = _f(msg.horizontal_dil)
        if quality == 0 or not msg.lat or not msg.lon:
            return Gps(t, None, None, None, 0, hdop)
        lat, lon = float(msg.latitude), float(msg.longitude)
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise ValueError("position out of range")
        alt = _f(msg.altitude)
        sep = _f(msg.geo_sep)
        h = None if alt is None else alt + (sep or 0.0)
        return Gps(t, lat, lon, h, 2 if quality == 2 else 1, hdop)

    def _rmc(self, msg: pynmea2.RMC, t: float) -> GpsTime:
        utc = None
        if msg.datestamp and msg.timestamp:
            utc = dt.datetime.combine(msg.datestamp, msg.timestamp).replace(tzinfo=dt.UTC)
        return GpsTime(t, utc, msg.status == "A")
