"""GPS receiver (Linx RXM-GPS-R4 and any NMEA 0183 receiver): GGA and RMC, sans-I/O.

Sentences are ``$<address>,...*hh`` closed by CR LF (NMEA 0183 v3, docs/protocols.md).
Real receivers also close lines with CR or LF alone, interleave binary protocols
(u-blox UBX, SiRF) and send proprietary ``$P...`` and other sentences unasked: the
framing here takes any of the three line ends, checks the checksum itself, and
counts by reason and sentence type everything it does not use, so nothing a
receiver says can raise.

GGA gives the fix: quality 0 none, 1 GPS, 2 DGPS and the differential kinds (6
estimated, 7 manual and 8 simulator are not fixes).  Its height is above mean sea
level; the ellipsoidal height (``alt``) is given only when the receiver sent the
geoid separation.  GGA's fields are read here (pynmea2 reads RMC's date), the
coordinates from their ``ddmm.mmmm`` text (pynmea2 would take 75 minutes as a
degree and a quarter): minutes of 60 or
more, a latitude past 90 or a missing hemisphere refuse the sentence.  Receivers
that report per constellation send one GGA per talker for one epoch (GP and GL,
GP and GA): the first is the fix, the others are counted as ``duplicate_epoch``.
Every number is held to ``navd.records.BOUNDS``.  RMC gives UTC date and time and
the receiver's validity flag.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import pynmea2

from navd.drivers.codec import DecodeStats
from navd.records import Gps, implausible

# NMEA allows 82 characters; high-precision and proprietary sentences of real
# receivers reach about 120.  A longer "line" is binary or garbage.
_MAX_LINE = 256
_LINE_ENDS = b"\r\n"
# GGA quality (field 6) to the record's fix: 1 GPS, 3 PPS; 2 DGPS, 4 RTK fixed, 5 RTK
# float, 9 WAAS (all differential).  6 estimated, 7 manual and 8 simulator are not fixes.
_FIX_OF_QUALITY = {1: 1, 3: 1, 2: 2, 4: 2, 5: 2, 9: 2}
# distinct sentence names counted by name; past this, a hostile or broken stream of
# well-formed nonsense is counted under one name, so health stays bounded
_MAX_KINDS = 32
_HEX = frozenset("0123456789ABCDEFabcdef")


@dataclass(frozen=True, slots=True)
class GpsTime:
    t: float
    utc: dt.datetime | None
    valid: bool


class Epochs:
    """One fix per epoch: a second report of the epoch just fused (another talker's
    GGA, gpsd's TPV of another sentence of the cycle) within a second is a duplicate.
    Within a second only: a receiver whose clock is stuck still gives a fix a second."""

    def __init__(self, stats: DecodeStats) -> None:
        self.stats = stats
        self._last: tuple[str, float] | None = None

    def clear(self) -> None:
        # after a decoder fault: the failed read's fix was never delivered
        self._last = None

    def duplicate(self, epoch: str | None, t: float) -> bool:
        last = self._last
        if epoch is not None and last is not None and epoch == last[0] and t - last[1] < 1.0:
            self.stats.reasons["duplicate_epoch"] = self.stats.reasons.get("duplicate_epoch", 0) + 1
            return True
        return False

    def took(self, epoch: str | None, t: float) -> None:
        if epoch is not None:
            self._last = (epoch, t)


class _Refused(Exception):
    """A sentence that framed and checked but cannot be used; the reason is counted."""


def _f(s: str) -> float | None:
    """A decimal field, None if empty; anything but a plain decimal (``nan``, ``1e9``)
    refuses the sentence."""
    if not s:
        return None
    digits = s[1:] if s[0] in "+-" else s
    if len(s) > 16 or not digits.replace(".", "", 1).isdigit() or not digits.isascii():
        raise _Refused("bad_number")
    return float(s)


def _coordinate(text: str, hemi: str, max_deg_digits: int, limit: float, neg: str) -> float:
    """Degrees from NMEA ``(d)ddmm.mmmm`` and its hemisphere letter.

    The minutes are the two digits before the point and the fraction after it, the
    degrees whatever precedes them (as gpsd reads it: some receivers drop leading
    zeros)."""
    dot = text.find(".")
    whole = text if dot < 0 else text[:dot]
    frac = "" if dot < 0 else text[dot + 1 :]
    if len(whole) < 2 or len(whole) > max_deg_digits + 2:
        raise _Refused("bad_coordinate")
    if not whole.isdigit() or not (frac == "" or frac.isdigit()) or not whole.isascii():
        raise _Refused("bad_coordinate")
    deg = int(whole[:-2] or "0")
    minutes = float(whole[-2:] + ("." + frac if frac else ""))
    if minutes >= 60.0:
        raise _Refused("minutes_out_of_range")
    value = deg + minutes / 60.0
    if value > limit:
        raise _Refused("coordinate_out_of_range")
    return -value if hemi == neg else value


def _int(s: str) -> int | None:
    return int(s) if s and s.isdigit() and s.isascii() and len(s) <= 3 else None


class NmeaDecoder:
    def __init__(self) -> None:
        self.stats = DecodeStats()
        self._buf = bytearray()
        self._epochs = Epochs(self.stats)

    def reset(self) -> None:
        self._buf.clear()
        self._epochs.clear()

    def feed(self, data: bytes, t: float) -> list[object]:
        self.stats.bytes_in += len(data)
        buf = self._buf
        buf += data
        out: list[object] = []
        while buf:
            # line ends between sentences are not garbage: CR LF leaves a lone LF
            n = 0
            while n < len(buf) and buf[n] in _LINE_ENDS:
                n += 1
            start = buf.find(b"$", n)
            if start < 0:
                if len(buf) > n:
                    self.stats.skip(len(buf) - n, "no_start")
                buf.clear()
                break
            if start > n:
                self.stats.skip(start - n, "no_start")
            del buf[:start]
            end = _line_end(buf)
            nxt = buf.find(b"$", 1, end if end >= 0 else len(buf))
            if nxt > 0:
                # a sentence cut short by the next one
                self.stats.skip(nxt, "truncated")
                self.stats.bad_frame += 1
                del buf[:nxt]
                continue
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
            rec = self._sentence(line, t)
            if rec is not None:
                out.append(rec)
                self.stats.records += 1
        return out

    def _count(self, prefix: str, name: str) -> None:
        key = f"{prefix}_{name}"
        reasons = self.stats.reasons
        if key not in reasons and sum(k.startswith(prefix) for k in reasons) >= _MAX_KINDS:
            key = f"{prefix}_other"
        reasons[key] = reasons.get(key, 0) + 1

    def _sentence(self, line: bytes, t: float) -> object | None:
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            self.stats.bad_frame += 1
            self.stats.skip(len(line), "unparseable")
            return None
        text = text.strip()
        star = text.rfind("*")
        if star < 0:
            self.stats.bad_checksum += 1  # a sentence without its checksum is not trusted
            self.stats.skip(len(line), "no_checksum")
            return None
        body, given = text[1:star], text[star + 1 :]
        if len(given) != 2 or not set(given) <= _HEX:
            self.stats.bad_checksum += 1
            self.stats.skip(len(line), "checksum")
            return None
        sum_ = 0
        for c in body.encode("ascii"):
            sum_ ^= c
        if sum_ != int(given, 16):
            self.stats.bad_checksum += 1
            self.stats.skip(len(line), "checksum")
            return None
        address = body.split(",", 1)[0]
        name = address if address.isalnum() and len(address) <= 8 else "other"
        if address.startswith("P"):
            self._count("proprietary", name)  # $PGLOR, $PUBX, $PASHR, $PMTK...: a vendor's
            return None
        kind = address[2:] if len(address) == 5 else ""
        if kind not in ("GGA", "RMC"):
            self._count("ignored", kind if kind and name != "other" else name)
            return None
        try:
            if kind == "GGA":
                return self._gga(body.split(",")[1:], t)
            return self._rmc(pynmea2.parse(text, check=False), t)
        except _Refused as why:
            self.stats.bad(str(why))
            return None
        except Exception:  # pynmea2 is a third-party parser: whatever it raises is our "no"
            self.stats.bad_frame += 1
            self.stats.skip(len(line), "bad_fields")
            return None

    def _gga(self, f: list[str], t: float) -> Gps | None:
        """GGA from its fields after the address: time, lat, N/S, lon, E/W, quality,
        satellites, HDOP, altitude, M, separation, M, ..."""
        if len(f) < 12:
            raise _Refused("short_gga")
        qual_text = f[5] or "0"
        if not (qual_text.isdigit() and qual_text.isascii() and len(qual_text) == 1):
            raise _Refused("bad_quality")
        quality = int(qual_text)
        hdop = _f(f[7])
        # an empty satellites field on a fix says no more than 0: both are "used none
        # that it will name", which with no HDOP is a fix of unknown geometry
        sats = _int(f[6]) if f[6] else 0
        fix = _FIX_OF_QUALITY.get(quality, 0)
        if quality not in _FIX_OF_QUALITY and quality != 0:
            # 6 estimated (dead reckoning), 7 manual input, 8 simulator: not a position fix
            self._count("quality", str(quality))
        if fix == 0 or not f[1] or not f[3]:
            return Gps(t, None, None, None, 0, hdop, quality, sats=sats)
        if f[2] not in ("N", "S") or f[4] not in ("E", "W"):
            # a missing hemisphere would put the fix at the wrong place
            raise _Refused("bad_hemisphere")
        lat = _coordinate(f[1], f[2], 2, 90.0, "S")
        lon = _coordinate(f[3], f[4], 3, 180.0, "W")
        epoch = f[0] or None
        if self._epochs.duplicate(epoch, t):
            return None
        alt_msl = _f(f[8])
        sep = _f(f[10])
        alt = None if alt_msl is None or sep is None else alt_msl + sep
        rec = Gps(t, lat, lon, alt, fix, hdop, quality, alt_msl, sep, sats)
        if implausible(rec) is not None:
            raise _Refused("implausible")
        self._epochs.took(epoch, t)
        return rec

    def _rmc(self, msg: pynmea2.RMC, t: float) -> GpsTime:
        utc = None
        if msg.datestamp and msg.timestamp:
            utc = dt.datetime.combine(msg.datestamp, msg.timestamp).replace(tzinfo=dt.UTC)
        return GpsTime(t, utc, msg.status == "A")


def _line_end(buf: bytearray) -> int:
    """Index of the first CR or LF in ``buf``, or -1."""
    cr, lf = buf.find(b"\r"), buf.find(b"\n")
    if cr < 0:
        return lf
    return cr if lf < 0 else min(cr, lf)
