"""gpsd as a GPS source: its JSON reports to the same ``gps`` records as NMEA, sans-I/O.

On a vehicle the receiver is often gpsd's, shared with chrony.  After
``?WATCH={"enable":true,"json":true}`` gpsd sends one JSON object a line
(https://gpsd.io/gpsd_json.html): ``TPV`` for position, heights (``altHAE``
above the ellipsoid, ``altMSL`` above the geoid, ``geoidSep``), ``mode`` (1 no
fix, 2 2D, 3 3D), ``status`` (2 DGPS, 3 RTK fixed, 4 RTK float, 5 and 6 dead
reckoning, 7 time only, 8 simulated) and time; ``SKY`` for HDOP and the
satellites used.  gpsd may report one epoch more than once (a TPV per sentence of
a cycle): the first is the fix, as with several talkers' GGAs.  Everything else
(VERSION, DEVICES, WATCH, ...) is counted and skipped; nothing raises.
"""

from __future__ import annotations

import math

from navd.drivers.codec import DecodeStats
from navd.drivers.gps import Epochs, GpsTime
from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.records import Gps, implausible
from navd.utc import utc_time

#: what navd sends gpsd on connecting: JSON reports, no NMEA
WATCH = b'?WATCH={"enable":true,"json":true}\n'
DEFAULT_PORT = 2947
_MAX_LINE = 65536  # a SKY with every satellite in view is a few kB
# gpsd's status to GGA's quality (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float); a TPV
# without a status is a plain GPS fix.  Dead reckoning, time-only and simulated
# reports are not position fixes.
_QUALITY_OF_STATUS = {1: 1, 2: 2, 3: 4, 4: 5}
_NOT_FIX_STATUS = frozenset({5, 6, 7, 8})


def _num(o: JsonObject, key: str) -> float | None:
    v = o.get(key)
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    return float(v) if math.isfinite(v) else None


class GpsdDecoder:
    def __init__(self) -> None:
        self.stats = DecodeStats()
        self._buf = bytearray()
        self._hdop: float | None = None  # from the last SKY
        self._sats: int | None = None
        self._epochs = Epochs(self.stats)

    def reset(self) -> None:
        self._buf.clear()
        self._epochs.clear()

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        buf = self._buf
        buf += data
        out: list[object] = []
        while True:
            end = buf.find(b"\n")
            if end < 0:
                if len(buf) > _MAX_LINE:
                    self.stats.too_long(len(buf))
                    buf.clear()
                break
            line = bytes(buf[:end])
            del buf[: end + 1]
            if len(line) > _MAX_LINE:
                self.stats.too_long(len(line))
                continue
            if not line.strip():
                continue
            for rec in self._report(line, t):
                out.append(rec)
                self.stats.records += 1
        return out

    def _report(self, line: bytes, t: float) -> list[object]:
        try:
            o = jsonlines.loads(line)
        except jsonlines.DecodeError:
            self.stats.bad_frame += 1
            self.stats.skip(len(line), "not_json")
            return []
        if not isinstance(o, dict):
            self.stats.bad("not_an_object")
            return []
        cls = o.get("class")
        if cls == "TPV":
            return self._tpv(o, t)
        if cls == "SKY":
            self._sky(o)
            return []
        name = cls if isinstance(cls, str) and cls.isalnum() and len(cls) <= 12 else "other"
        key = f"ignored_{name}"
        if key in self.stats.reasons or len(self.stats.reasons) < 32:
            self.stats.reasons[key] = self.stats.reasons.get(key, 0) + 1
        return []

    def _sky(self, o: JsonObject) -> None:
        self._hdop = _num(o, "hdop")
        used = o.get("uSat")
        if isinstance(used, int) and not isinstance(used, bool):
            self._sats = used
        elif isinstance(sats := o.get("satellites"), list):
            self._sats = sum(1 for s in sats if isinstance(s, dict) and s.get("used") is True)

    def _tpv(self, o: JsonObject, t: float) -> list[object]:
        out: list[object] = []
        utc = utc_time(o.get("time"))
        mode = o.get("mode")
        if utc is not None:
            out.append(GpsTime(t, utc, isinstance(mode, int) and mode >= 2))
        status = o.get("status", 1)
        if not isinstance(status, int) or isinstance(status, bool):
            self.stats.bad("bad_status")
            return out
        lat, lon = _num(o, "lat"), _num(o, "lon")
        if mode not in (2, 3) or lat is None or lon is None or status in _NOT_FIX_STATUS:
            out.append(Gps(t, None, None, None, 0, self._hdop, 0, sats=self._sats))
            return out
        quality = _QUALITY_OF_STATUS.get(status, 1)
        epoch = when if isinstance(when := o.get("time"), str) else None
        if self._epochs.duplicate(epoch, t):
            return out
        alt_msl = _num(o, "altMSL")
        if alt_msl is None:
            alt_msl = _num(o, "alt")  # gpsd before 3.20: MSL
        rec = Gps(
            t,
            lat,
            lon,
            _num(o, "altHAE") if mode == 3 else None,
            2 if quality != 1 else 1,
            self._hdop,
            quality,
            alt_msl if mode == 3 else None,
            _num(o, "geoidSep"),
            self._sats,
        )
        if implausible(rec) is not None:
            self.stats.bad("implausible")
            return out
        self._epochs.took(epoch, t)
        out.append(rec)
        return out
