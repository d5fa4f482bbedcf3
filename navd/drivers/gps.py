"""GPS receiver (Linx RXM-GPS-R4 and any NMEA 0183 receiver): GGA and RMC, sans-I/O.

Sentences are ``$<talker><type>,...*hh<CR><LF>`` (NMEA 0183 v3, docs/protocols.md);
pynmea2 parses them.  GGA gives the fix: quality 0 none, 1 GPS, 2 DGPS and the
differential kinds (6 estimated, 7 manual and 8 simulator are not fixes), and
altitude above mean sea level plus the geoid separation, which makes the
ellipsoidal height the filter wants.  Every number is held to the bounds of
``navd.records.BOUNDS`` and hemispheres must be given.  Empty fields before a fix give a ``fix 0``
record.  RMC gives UTC date and time and the receiver's validity flag.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import pynmea2

from navd.drivers.codec import DecodeStats
from navd.records import Gps, implausible

_MAX_LINE = 120  # NMEA allows 82 characters; anything much longer is garbage
# GGA quality (field 6) to the record's fix: 1 GPS, 3 PPS; 2 DGPS, 4 RTK fixed, 5 RTK
# float, 9 WAAS (all differential).  6 estimated, 7 manual and 8 simulator are not fixes.
_FIX_OF_QUALITY = {1: 1, 3: 1, 2: 2, 4: 2, 5: 2, 9: 2}


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

    def _gga(self, msg: pynmea2.GGA, t: float) -> Gps | None:
        quality = int(msg.gps_qual or 0)
        hdop = _f(msg.horizontal_dil)
        fix = _FIX_OF_QUALITY.get(quality, 0)
        if quality not in _FIX_OF_QUALITY and quality != 0:
            # 6 estimated (dead reckoning), 7 manual input, 8 simulator: not a position fix
            self.stats.reasons[f"quality_{quality}"] = (
                self.stats.reasons.get(f"quality_{quality}", 0) + 1
            )
        if fix == 0 or not msg.lat or not msg.lon:
            return Gps(t, None, None, None, 0, hdop, quality)
        if msg.lat_dir not in ("N", "S") or msg.lon_dir not in ("E", "W"):
            # pynmea2 reads a missing hemisphere as north/east: that would be a fix at
            # the wrong place (or 0, 0), so the sentence is refused
            self.stats.bad("bad_hemisphere")
            return None
        lat, lon = float(msg.latitude), float(msg.longitude)
        alt = _f(msg.altitude)
        sep = _f(msg.geo_sep)
        h = None if alt is None else alt + (sep or 0.0)
        rec = Gps(t, lat, lon, h, fix, hdop, quality)
        why = implausible(rec)
        if why is not None:
            self.stats.bad("implausible")
            return None
        return rec

    def _rmc(self, msg: pynmea2.RMC, t: float) -> GpsTime:
        utc = None
        if msg.datestamp and msg.timestamp:
            utc = dt.datetime.combine(msg.datestamp, msg.timestamp).replace(tzinfo=dt.UTC)
        return GpsTime(t, utc, msg.status == "A")
