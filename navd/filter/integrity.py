"""Integrity: can the autopilot trust the estimate, or should it surface?

Every estimate carries ``integrity``: ``ok``, ``degraded`` or ``lost``, from two
tests that do not need the truth:

* **Consistency.**  Over the last ``window`` ranges the filter fused, the
  normalised innovations squared (NIS, nu^2 / S) of a consistent filter are
  chi-square distributed with one degree of freedom each, so their sum lies below
  the 99 % quantile of chi-square with that many degrees of freedom (Bar-Shalom,
  Li and Kirubarajan 2001, section 5.4).  A larger sum means the covariance
  claims more than the ranges show: the estimate is overconfident.  A window in
  which the gate refused most ranges says the filter and its ranges disagree.
* **Covariance.**  The largest one-sigma axis of the position ellipse against
  ``degraded_std_m`` and ``lost_std_m``.
* **Resumed.**  An estimate resumed from a checkpoint after a restart is
  ``degraded`` until ``CONFIRM_RESUMED`` ranges have been accepted (or a GPS fix).
* **A run of refusals.**  Ranges or GPS fixes refused in a row, however few the
  window holds (a GPS fix empties it): ``degraded_refused`` of them is degraded,
  ``lost_refused`` lost.  Each refusal says the estimate and its inputs disagree.
* **A range refused as short.**  Multipath only lengthens a reply, so a range the gate
  refuses for reading shorter than the estimate predicts says the estimate is off, not
  the range (or that the beacon is not where it reports): degraded until a range is
  accepted.  One is enough: a filter that has taken a reflection for a true reply
  refuses the true ones after it as short, and while a run of them built up it was
  ``ok`` and far off (BENCHMARKS.md, "A range refused as short").
* **A range nothing has checked.**  After a gap the estimate is uncertain along the line
  of sight, the gate is wide, and the first reply accepted places the estimate almost
  alone (its update moves it by more than ``UNCHECKED_PULL`` of its residual).  A
  reflection a few tens of metres long passes that gate at full weight, and nothing can
  tell it from a true reply until the next one: degraded until a range is accepted
  that the estimate it placed could have refused (BENCHMARKS.md, "A reply after a gap,
  unchecked (session 43)").

``lost`` means no range agrees with the estimate any more, or its own
uncertainty is past the site's limit; an autopilot should surface for GPS.
"""

from __future__ import annotations

import math
from collections import deque

OK, DEGRADED, LOST = "ok", "degraded", "lost"
#: accepted ranges that confirm an estimate resumed from a checkpoint
CONFIRM_RESUMED = 3
#: the share of its residual beyond which an accepted range placed the estimate alone:
#: the prior's variance along its line of sight four times the range's own
UNCHECKED_PULL = 0.8


def chi2_quantile(p: float, dof: int) -> float:
    """Quantile of chi-square (Wilson and Hilferty 1931), within 1 % for dof >= 1 at p = 0.99."""
    # the standard normal quantile at p by Abramowitz and Stegun 26.2.23 (|error| < 4.5e-4)
    q = 1.0 - p
    t = math.sqrt(-2.0 * math.log(q))
    z = t - (2.515517 + 0.802853 * t + 0.010328 * t * t) / (
        1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t**3
    )
    k = 2.0 / (9.0 * dof)
    return dof * (1.0 - k + z * math.sqrt(k)) ** 3


class Integrity:
    def __init__(
        self,
        window: int,
        degraded_std_m: float,
        lost_std_m: float,
        degraded_refused: int = 3,
        lost_refused: int = 8,
    ) -> None:
        self.degraded_std_m = degraded_std_m
        self.lost_std_m = lost_std_m
        self.degraded_refused = degraded_refused
        self.lost_refused = lost_refused
        self.refused_run = 0  # ranges or fixes refused in a row
        self.refused_short = False  # since the last accepted range, one refused as short
        self.unchecked = False  # the last accepted range placed the estimate alone
        # resumed from a checkpoint: degraded until ranges (or a fix) confirm it
        self.unconfirmed: str = ""
        self._confirming = 0
        self._ranges: deque[tuple[bool, float]] = deque(maxlen=window)
        self.reason = ""
        # what assess() needs of the window, worked out when it changes (a range) rather
        # than at every estimate
        self._rejected = 0
        self._nis: list[float] = []
        self._nis_limit = math.inf

    def clear(self) -> None:
        """A position fix (GPS) or a restart: the ranges before it say nothing now."""
        self._ranges.clear()
        self.refused_run = 0
        self.refused_short = False
        self.unchecked = False
        self.unconfirmed, self._confirming = "", 0
        self._summarise()

    def resumed(self, why: str) -> None:
        """The estimate came from a checkpoint, not from this run's measurements."""
        self.clear()
        self.unconfirmed = why

    def range(
        self, accepted: bool, nis: float, short: bool = False, pull: float = math.nan
    ) -> None:
        """A range the filter accepted or refused, its NIS, whether it read shorter than
        predicted, and the share of its residual the update moved the estimate by along its
        line of sight (NaN: not known)."""
        self._ranges.append((accepted, nis))
        self.refused_run = 0 if accepted else self.refused_run + 1
        self.refused_short = not accepted and (short or self.refused_short)
        if accepted:
            self.unchecked = pull > UNCHECKED_PULL
        if accepted and self.unconfirmed:
            self._confirming += 1
            if self._confirming >= CONFIRM_RESUMED:
                self.unconfirmed = ""
        self._summarise()

    def fix_refused(self) -> None:
        """A GPS fix the gate refused: the estimate and the receiver disagree."""
        self.refused_run += 1

    def _summarise(self) -> None:
        window = self._ranges
        self._rejected = sum(1 for ok, _ in window if not ok)
        self._nis = [v for ok, v in window if ok and math.isfinite(v)]
        n = len(self._nis)
        self._nis_limit = chi2_quantile(0.99, n) if n >= 3 else math.inf

    def assess(self, std_max_m: float) -> str:
        """The state, with ``reason`` saying why when it is not ``ok``."""
        self.reason = ""
        if not math.isfinite(std_max_m) or std_max_m > self.lost_std_m:
            self.reason = f"position std {std_max_m:.0f} m over {self.lost_std_m:g} m"
            return LOST
        window = self._ranges
        full = len(window) == window.maxlen
        rejected = self._rejected
        if full and rejected == len(window):
            self.reason = f"the last {len(window)} ranges all refused"
            return LOST
        if self.refused_run >= self.lost_refused:
            self.reason = f"{self.refused_run} ranges or fixes refused in a row"
            return LOST
        if std_max_m > self.degraded_std_m:
            self.reason = f"position std {std_max_m:.0f} m over {self.degraded_std_m:g} m"
            return DEGRADED
        if self.refused_run >= self.degraded_refused:
            self.reason = f"{self.refused_run} ranges or fixes refused in a row"
            return DEGRADED
        if self.refused_short:
            self.reason = "a range refused as reading short"
            return DEGRADED
        if self.unchecked:
            self.reason = "one range placed the estimate, and none has checked it yet"
            return DEGRADED
        if self.unconfirmed:
            self.reason = self.unconfirmed
            return DEGRADED
        nis = self._nis
        if len(nis) >= 3 and sum(nis) > self._nis_limit:
            self.reason = f"ranges disagree with the covariance (NIS {sum(nis):.1f} in {len(nis)})"
            return DEGRADED
        if full and rejected > len(window) // 2:
            self.reason = f"{rejected} of the last {len(window)} ranges refused"
            return DEGRADED
        return OK
