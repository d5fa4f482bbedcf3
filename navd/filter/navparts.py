"""What the navigator holds (navd/filter/navigator.py): the filter of the configured
mode, the parts beside it, and the rule that starts them again.

The navigator is one object split into files by concern, as AP_NavEKF3 splits its
core: these parts and what they say (here); GPS fixes and ranges
(navd/filter/navfusion.py); a restart's snapshot and resume
(navd/filter/navresume.py); time and dispatch (navd/filter/navigator.py).
"""

from __future__ import annotations

import math
from collections import Counter

from navd.filter.bank import CalibrationBank
from navd.filter.common import NavFilter
from navd.filter.deadreckoning import DeadReckoner
from navd.filter.depth import DepthGauge
from navd.filter.dvl import DvlDeadReckoner, DvlSpec
from navd.filter.ekf import RangeEKF
from navd.filter.gpsfix import DEPTH_TRUST_S, GpsFixes, GpsGate
from navd.filter.inputs import HeldInputs
from navd.filter.integrity import Integrity
from navd.filter.ranging import Ranging
from navd.filter.smoothing import Smoothing
from navd.filter.thesis import ThesisEKF
from navd.filter.tide import TidePrediction
from navd.filter.vlblmode import VlblMode
from navd.schema import Advisory
from navd.settings import Config


def make_filter(cfg: Config, tide: TidePrediction | None = None) -> NavFilter:
    """The configured mode's filter; the default mode's follows ``tide`` (the crew's
    tidal prediction, navd/filter/tide.py) where given."""
    nav = cfg.navigation
    nz = nav.noise
    if nav.filter == "vlbl":
        return VlblMode()
    if nav.filter == "thesis":
        return ThesisEKF(
            nz.position_init_std_m,
            nz.current_init_std_mps,
            nz.thesis_position_walk_m_per_sqrt_s,
            nz.thesis_current_walk_mps_per_sqrt_s,
        )
    g = nav.gate
    sound = nav.sound_speed
    config = RangeEKF(
        nz, g.chi2, g.chi2_long, g.reacquire_after, nav.max_current_mps,
        sound_speed_rel_std=sound.std_mps / sound.model_obj().at(0.0),
    )  # fmt: skip
    config.tide = tide
    return CalibrationBank(config)


class NavParts:
    def __init__(self, cfg: Config, keep_history: bool = False) -> None:
        self.cfg = cfg
        self.nav = cfg.navigation
        self.counters: Counter[str] = Counter()
        # the RTS smoother's record of the run, kept only when asked for
        self.smoothing: Smoothing | None = Smoothing() if keep_history else None
        # the crew's tidal prediction, with the clock the navigator is told (a restart's
        # fresh filters keep both)
        self.tide = TidePrediction.from_config(cfg.navigation.tide)
        # UTC at t = 0 by the computer's clock (the daemon's, a log's header): what a new
        # process starts the prediction with, until the GPS receiver says otherwise
        self.computer_clock: float | None = None
        self.clock_from_gps = False  # the prediction's clock is the receiver's
        self._fresh()

    def _fresh(self) -> None:
        """Everything a new process knows before its first record (counters and the
        smoother's finished segments are the run's, and stay)."""
        cfg = self.cfg
        nav = self.nav
        if self.tide is not None:
            self.tide.offset_s = self.computer_clock
        self.clock_from_gps = False
        self.filter: NavFilter = make_filter(cfg, self.tide)
        if self.smoothing is not None:
            self.smoothing.start(self.filter)
        self.dr = DeadReckoner()
        d = nav.dvl
        self.dvl = DvlDeadReckoner(
            DvlSpec(
                d.velocity_error_frac,
                d.attitude_error_deg,
                d.max_accel_mps2,
                d.max_rejections,
                d.error_limit_m,
            ),
            math.radians(nav.magnetic_declination_deg),
        )
        self._dvl_seen = False
        self.ranging = Ranging(cfg, self.counters)
        self.tick_dt = 1.0 / nav.rate_hz
        ig = nav.integrity
        self.integrity = Integrity(
            ig.window, ig.degraded_std_m, ig.lost_std_m, ig.degraded_refused, ig.lost_refused
        )
        self.warnings: list[str] = list(self.ranging.sound.warnings())

        self._tick_k: int | None = None
        self._t_filter: float | None = None
        self.inputs = HeldInputs(nav)
        self.depth = DepthGauge(cfg.site)
        self.gps = GpsFixes(nav, cfg.site)
        self.gps_gate = GpsGate(nav.gate.gps_chi2, nav.gate.gps_agree)

    def restart(self, reason: str) -> None:
        """Forget the estimate and start again at the next GPS fix."""
        self.counters[f"restarts_{reason}"] += 1
        self.filter = make_filter(self.cfg, self.tide)
        if self.smoothing is not None:
            self.smoothing.start(self.filter)
        self.integrity.clear()
        self.ranging.observability.clear()
        self.dr = DeadReckoner()
        self._tick_k = None
        self._t_filter = None
        self.gps.forget()
        self.gps_gate.clear()

    # -- what they say -------------------------------------------------------------------
    @property
    def surface_altitude(self) -> float:
        return self.gps.surface_altitude

    def _at_surface(self) -> bool:
        return self.depth.m < self.nav.surface_depth_m

    def advisory(self, t: float, heading_deg: float | None) -> Advisory:
        """How well the recent ranges fix each direction (navd/filter/advisory.py)."""
        return self.ranging.observability.assess(t, heading_deg)

    def input_ages(self, t: float) -> dict[str, float | None]:
        """Seconds since the last heading, RPM and depth (None: never seen)."""
        i = self.inputs
        ages = {"heading": i.t_heading, "rpm": i.t_rpm, "depth": self.depth.t}
        return {k: (t - v if math.isfinite(v) else None) for k, v in ages.items()}

    def mode(self, t: float) -> str:
        depth_stale = t - self.depth.t > DEPTH_TRUST_S
        if not self._at_surface() and not (depth_stale and self.gps.fresh(t)):
            return "submerged"
        if self.gps.warmed_up(t):
            return "surface"
        return "surfacing"
