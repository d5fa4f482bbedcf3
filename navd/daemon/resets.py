"""How often the autopilot may reset navd.

Each reset stops the estimates until the next GPS fix, so their rate is bounded:
no run of resets, however well-formed, can keep navd from navigating.  Submerged,
the filter cannot start again until the vehicle surfaces, so a reset there must be
forced, and a forced one is rarer still.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

RESET_SPACING_S = 10.0  # any reset at most this often
FORCED_RESET_SPACING_S = 60.0  # a forced one (it stops navigation until the next fix)


@dataclass(slots=True)
class ResetRule:
    t_reset: float = -math.inf  # the last accepted reset, and the last forced one
    t_forced: float = -math.inf

    def allow(self, t: float, submerged: bool, force: bool) -> str | None:
        """None, and the reset is counted as made at ``t``; or why it is refused."""
        if submerged and not force:
            return "submerged: a reset stops navigation until the next GPS fix; send force"
        since = t - self.t_reset
        if since < RESET_SPACING_S:
            return f"a reset {since:.1f} s ago: at most one every {RESET_SPACING_S:g} s"
        if force and t - self.t_forced < FORCED_RESET_SPACING_S:
            return f"a forced reset at most once every {FORCED_RESET_SPACING_S:g} s"
        self.t_reset = t
        if force:
            self.t_forced = t
        return None
