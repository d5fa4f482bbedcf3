"""A crew's prediction of its site's tidal stream, as a known change of the current.

The current is a random walk (docs/replay.md, "A current that changes").  A tidal stream
that turns during a mission changes faster than a walk that keeps the filter honest
elsewhere, and one beacon cannot see the change across its line of sight: on the Monte
Carlo's turning streams that walk left the default mode at 2.5 times the Cramer-Rao
bound (BENCHMARKS.md, "A crew's tidal prediction").  Yet a tidal site's crew knows its
stream's form: tidal current predictions (NOAA's, an admiralty chart's tidal diamonds)
give the flood direction and the time and speed of maximum flood.

navd takes that prediction as a rectilinear semidiurnal stream,

    v(t) = A cos(2 pi (t - t_flood) / T) (cos theta, sin theta),

and moves the filter's current by the prediction's change over each step, a known input
to the current's transition (a control input: Simon, *Optimal State Estimation*, 2006,
ch. 5).  The current state still holds the whole current, and what the prediction leaves
out (its errors of size, time and direction, a mean stream) is what the walk and the
ranges follow.  The current's prior mean is the prediction: at the start, and where the
bank tests the config's priors (navd/filter/bank.py).

What the prediction may miss still turns with the tide, and one beacon still cannot see
it across its line of sight: the default mode's ellipse allows for a turning stream as
strong as the prediction's stated error (``error_fraction`` of its amplitude) in place of
the site's strongest (navd/filter/bank.py), once the prediction is followed.

The prediction is in UTC; the filter's time is the records' (monotonic seconds live,
the log's seconds in replay).  The navigator learns the offset between them from the
log's header or the daemon's clock, and from the GPS receiver's UTC where those are off
(``offset_s``; navd/filter/navigator.py); until then the prediction is not used.

Sans I/O and total: a velocity that is not finite is no prediction (``None``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from navd.settings import TideConfig
from navd.utc import utc_seconds

__all__ = ["TidePrediction"]


@dataclass(slots=True)
class TidePrediction:
    amplitude_mps: float
    toward_rad: float  # the flood's direction, true, clockwise from north
    period_s: float
    flood_utc_s: float  # an instant of maximum flood, UTC seconds since the epoch
    # how far the prediction may be off, as a fraction of its amplitude
    error_fraction: float = 0.5
    # UTC seconds at filter time 0: unknown (None) until the navigator is told
    offset_s: float | None = None

    @staticmethod
    def from_config(tc: TideConfig) -> TidePrediction | None:
        """The configured prediction; None when there is none (no amplitude)."""
        flood = utc_seconds(tc.max_flood_utc)
        if not (tc.amplitude_mps > 0.0 and flood is not None):
            return None
        return TidePrediction(
            tc.amplitude_mps, math.radians(tc.toward_deg), tc.period_s, flood, tc.error_fraction
        )

    def __deepcopy__(self, memo: dict[int, object]) -> TidePrediction:
        # one prediction and one clock for every filter of a run, copies too (a net's
        # twin, navd/filter/mirror.py): the navigator sets the clock once for all
        return self

    @property
    def in_use(self) -> bool:
        """Whether the filters follow the prediction (its clock is known)."""
        return self.offset_s is not None

    @property
    def unknown_mps(self) -> float:
        """The amplitude of the turning stream the prediction may miss."""
        return self.error_fraction * self.amplitude_mps

    def velocity(self, t: float) -> tuple[float, float] | None:
        """The predicted stream (north, east, m/s) at filter time ``t``; None while the
        clock is unknown."""
        if self.offset_s is None:
            return None
        phase = 2.0 * math.pi * ((t + self.offset_s - self.flood_utc_s) / self.period_s)
        s = self.amplitude_mps * math.cos(phase)
        vn, ve = s * math.cos(self.toward_rad), s * math.sin(self.toward_rad)
        if not (math.isfinite(vn) and math.isfinite(ve)):
            return None
        return vn, ve
