"""Which GPS fixes the filter may use, and how far to trust each.

A fix counts only with the antenna out of the water (depth says so, or depth is too
old to say otherwise), at a usable HDOP; its std grows with HDOP, an RTK fix has its
own, and a fix just after the receiver re-acquires is held to a warm-up floor because
its HDOP does not yet show how poor it is.  The fixes' mean altitude is the surface's.

A re-acquisition is what the receiver or the vehicle said: a report of no fix, a fix
while the antenna was under water, a depth that put it there, or a gap in the fixes.
A receiver already tracking when navd starts (on deck, or waiting at the surface for
the dive) sends fixes from its first sentence; one that is acquiring sends reports of no
fix first (an NMEA GGA of quality 0, gpsd's mode 1).  So the first fixes navd sees are
taken at their stated quality unless the receiver said otherwise: held to the floor,
the first 30 s of the minute at the surface before a dive, where the current is learnt,
counted for a twenty-fifth of their weight (BENCHMARKS.md, "A receiver already tracking
at the start").
"""

from __future__ import annotations

import math

from navd import geodesy
from navd.filter.common import StateEstimate
from navd.records import Gps
from navd.settings import NavigationConfig, SiteConfig

FRESH_S = 2.0  # a fix this recent means "GPS available" (seed 000 Algorithm 2, line 13)
NEW_STREAK_S = 5.0  # a gap longer than this means GPS was lost and re-acquired
# Depth older than this is not trusted to refuse a GPS fix: a fix can only come with
# the antenna out of the water, so a stalled pressure sensor must not keep the
# vehicle "submerged" after it has surfaced.
DEPTH_TRUST_S = 5.0
# A real-time kinematic receiver's horizontal error (fixed, float): far below an
# autonomous fix, whatever the configured std says
RTK_STD_M = {4: 0.05, 5: 0.5}


def fix_std(
    std_m: float, hdop: float | None, quality: int | None, sats: int | None = None,
    unknown_hdop: float = 1.0,
) -> float:
    """A fix's horizontal std: the configured std at HDOP 1, grown with HDOP (the
    range error times the geometry's dilution); an RTK fix gets its own.  A fix that
    names no satellite and gives no HDOP (AIS transponders, some differential
    outputs; ``sats`` 0) is taken as the poorest HDOP the filter accepts.  A record
    that does not carry ``sats`` at all (a log of another writer) is not judged so."""
    if hdop is None and sats == 0:
        hdop = unknown_hdop
    std = std_m * max(1.0, hdop or 1.0)
    if quality in RTK_STD_M:
        std = min(std, RTK_STD_M[quality] * max(1.0, hdop or 1.0))
    return std


class GpsFixes:
    def __init__(self, nav: NavigationConfig, site: SiteConfig) -> None:
        self.nav = nav
        self.site = site
        self.t_last: float | None = None  # the last fix used
        self.t_streak = -math.inf  # since when fixes have come without a gap
        # the receiver lost its fix since the last one, so the next streak re-acquires
        self._lost = False
        self._reacquiring = False  # the streak under way began with a re-acquisition
        self._alt_sum = 0.0
        self._alt_n = 0

    def forget(self) -> None:
        """A restart: the next fix starts the filter."""
        self.t_last = None

    def fresh(self, t: float) -> bool:
        return self.t_last is not None and t - self.t_last <= FRESH_S

    def warmed_up(self, t: float) -> bool:
        return self.fresh(t) and not self._warming(t)

    def _warming(self, t: float) -> bool:
        return self._reacquiring and t - self.t_streak < self.nav.gps.warmup_s

    def antenna_under(self) -> None:
        """Depth puts the antenna under water: the receiver is losing its fix."""
        self._lost = True

    @property
    def surface_altitude(self) -> float:
        if self.site.surface_altitude_m is not None:
            return self.site.surface_altitude_m
        return self._alt_sum / self._alt_n if self._alt_n else 0.0

    def seed_altitude(self, alt: float) -> None:
        """The water's height as the run before a restart had measured it."""
        if self._alt_n == 0:
            self._alt_sum, self._alt_n = alt, 1

    def ellipsoidal_height(self, rec: Gps) -> float | None:
        """The fix's height above the ellipsoid: the receiver's, else its MSL height
        and the site's geoid separation; None rather than an MSL height taken for it."""
        if rec.alt is not None:
            return rec.alt
        if rec.alt_msl is not None and self.site.geoid_separation_m is not None:
            return rec.alt_msl + self.site.geoid_separation_m
        return None

    def judge(
        self, rec: Gps, at_surface: bool, t_depth: float
    ) -> tuple[float | None, list[str]]:
        """The std to fuse ``rec`` with (None: not used), and the counters it adds to."""
        if rec.fix == 0 or rec.lat is None or rec.lon is None:
            self._lost = True
            return None, ["gps_no_fix"]
        if rec.hdop is not None and rec.hdop > self.nav.gps.max_hdop:
            return None, ["gps_poor_hdop"]
        said = []
        if not at_surface:
            if rec.t - t_depth <= DEPTH_TRUST_S:
                self._lost = True
                return None, ["gps_while_submerged"]
            said.append("gps_with_stale_depth")
        if self.t_last is None or rec.t - self.t_last > NEW_STREAK_S:
            self.t_streak = rec.t
            self._reacquiring = self._lost or self.t_last is not None
        self._lost = False
        self.t_last = rec.t
        alt = self.ellipsoidal_height(rec)
        if alt is not None:
            self._alt_sum += alt
            self._alt_n += 1
        warm = self._warming(rec.t)
        std = fix_std(
            self.nav.noise.gps_std_m, rec.hdop, rec.quality, rec.sats, self.nav.gps.max_hdop
        )
        if warm and rec.quality not in RTK_STD_M:
            std = max(std, self.nav.gps.warmup_std_m)
        return std, said


#: the fastest the vehicle moves at the surface, for how far apart two fixes may be
SURFACE_SPEED_MAX_MPS = 3.0


class GpsGate:
    """GPS fixes gated like ranges: one far outside the estimate is refused.

    A fix is refused when its innovation, from the estimate with the estimate's
    covariance and the fix's own std, is past ``chi2`` on two degrees of freedom
    (Fulton 2000, seed 003: REMUS refuses a fix outside an error circle around its
    estimate).  One bad fix (a receiver's (0, 0), a corrupt sentence that passed its
    checksum) then costs nothing.  But an estimate that drifted beyond its own
    covariance underwater must still be corrected at the surface: refused fixes
    that agree with each other ``agree`` times in a row are the position, the same
    principle as re-acquisition from consistent evidence (filter/reacquire.py).
    """

    def __init__(self, chi2: float, agree: int) -> None:
        self.chi2 = chi2
        self.agree = agree
        self._refused: list[tuple[float, float, float, float]] = []  # t, n, e, std

    def clear(self) -> None:
        self._refused.clear()

    def judge(self, est: StateEstimate, lat: float, lon: float, std: float, t: float) -> str:
        """``fuse``, ``refuse``, or ``take`` (the refused fixes agree: restart at this one).

        ``lat``/``lon`` in radians, as the estimate's."""
        e, n, _ = geodesy.enu_offset(est.lat, est.lon, 0.0, lat, lon, 0.0)
        snn, see, sne = est.var_n + std**2, est.var_e + std**2, est.cov_ne
        det = snn * see - sne * sne
        d2 = (see * n * n - 2.0 * sne * n * e + snn * e * e) / det if det > 0 else math.inf
        if d2 <= self.chi2:
            self._refused.clear()
            return "fuse"
        # positions relative to the estimate: two fixes agree when no faster motion than
        # the surface's and their own errors separate them
        if self._refused:
            t0, n0, e0, s0 = self._refused[-1]
            apart = math.hypot(n - n0, e - e0)
            if apart > 3.0 * math.hypot(std, s0) + SURFACE_SPEED_MAX_MPS * (t - t0):
                self._refused.clear()
        self._refused.append((t, n, e, std))
        if len(self._refused) >= self.agree:
            self._refused.clear()
            return "take"
        return "refuse"
