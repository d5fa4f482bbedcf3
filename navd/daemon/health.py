"""Is navd navigating?  Judged from what it delivers, not from whether its ports are open.

A daemon can have every port open and every decoder counting good frames while
its navigation is dead: a pressure sensor that stopped answering leaves depth
frozen, a modem that never replies leaves the filter on dead reckoning, a
poisoned estimate is dropped tick after tick.  :class:`Vitals` keeps the few
facts that show these states (when estimates went out, when inputs last
arrived, how pings ended) and :meth:`Vitals.problems` names each state that is
not well.  It is pure: the caller passes the time.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

#: how many consecutive failed pings mean the modem or the deck box is not answering
FAILED_PINGS = 3
#: the window over which the estimate rate is measured
RATE_WINDOW_S = 5.0
#: a device error answer or an internal error is shown this long after it happened
RECENT_S = 30.0


@dataclass(slots=True)
class Vitals:
    rate_hz: float
    ping_interval_s: float
    stale_s: float
    estimates: deque[float] = field(default_factory=lambda: deque(maxlen=1000))
    pings: deque[str] = field(default_factory=lambda: deque(maxlen=FAILED_PINGS))
    t_range_accepted: float | None = None
    t_submerged: float | None = None  # when the vehicle last went under
    t_started: float = 0.0

    def estimate(self, t: float) -> None:
        self.estimates.append(t)

    def ping(self, outcome: str) -> None:
        """``range``, ``no_reply``, ``timeout`` or ``refused``."""
        self.pings.append(outcome)

    def range_accepted(self, t: float) -> None:
        self.t_range_accepted = t

    def navigating(self, now: float, initialised: bool) -> bool:
        """Estimates are coming out, or the filter is waiting for its first position
        (what systemd's watchdog is fed on)."""
        if not initialised:
            return True
        last = self.estimates[-1] if self.estimates else self.t_started
        return now - last <= 2.0

    def estimates_per_s(self, now: float) -> float:
        n = sum(1 for t in self.estimates if now - t <= RATE_WINDOW_S)
        return n / RATE_WINDOW_S

    def mode(self, now: float, mode: str) -> None:
        if mode == "submerged":
            if self.t_submerged is None:
                self.t_submerged = now
        else:
            self.t_submerged = None

    def problems(
        self, now: float, initialised: bool, input_ages: dict[str, float | None]
    ) -> list[str]:
        out = []
        rate = self.estimates_per_s(now)
        if not initialised:
            out.append("no estimates: waiting for a position (GPS or an acoustic fix)")
        elif now - self.t_started > RATE_WINDOW_S and rate < 0.9 * self.rate_hz:
            out.append(f"estimates at {rate:.1f}/s of {self.rate_hz:g}")
        for name, age in input_ages.items():
            if age is None:
                if now - self.t_started > max(5.0, 3 * self.stale_s):
                    out.append(f"{name}: never received")
            elif age > self.stale_s:
                out.append(f"{name}: stale for {age:.1f} s")
        if len(self.pings) == FAILED_PINGS and "range" not in self.pings:
            out.append(f"modem: the last {FAILED_PINGS} pings had no range")
        if self.t_submerged is not None:
            since = self.t_range_accepted if self.t_range_accepted else self.t_submerged
            quiet = now - max(since, self.t_submerged)
            if quiet > max(60.0, 6 * self.ping_interval_s):
                out.append(f"no accepted range for {quiet:.0f} s submerged")
        return out


def _ms(x: float | None) -> float | None:
    return None if x is None else round(x * 1000.0, 3)


class RecentTimes:
    """The last ``n`` of a stream of times, also kept in order of size as they come, so
    that a quantile is read once a second without sorting thousands of them each time
    (four sorts of 6,000 took about 3 ms of every second, by ``timeit``)."""

    __slots__ = ("_arrived", "_sorted")

    def __init__(self, n: int) -> None:
        self._arrived: deque[float] = deque(maxlen=n)
        self._sorted: list[float] = []

    def append(self, x: float) -> None:
        if not math.isfinite(x):
            return  # a clock's difference; a NaN would break the order
        if len(self._arrived) == self._arrived.maxlen:
            del self._sorted[bisect.bisect_left(self._sorted, self._arrived[0])]
        self._arrived.append(x)
        bisect.insort(self._sorted, x)

    def __len__(self) -> int:
        return len(self._arrived)

    def quantile(self, q: float) -> float | None:
        s = self._sorted
        return s[min(len(s) - 1, int(q * len(s)))] if s else None

    def max(self) -> float | None:
        return self._sorted[-1] if self._sorted else None


@dataclass(slots=True)
class TickTimes:
    """How late the filter's ticks ran, and how soon their estimates reached zenoh
    (from the tick's deadline), over the last 6,000 of each."""

    lateness: RecentTimes = field(default_factory=lambda: RecentTimes(6000))
    publish: RecentTimes = field(default_factory=lambda: RecentTimes(6000))
    overruns: int = 0
    ticks: int = 0

    def lateness_ms(self) -> dict[str, float | None]:
        lat = self.lateness
        return {
            "p50": _ms(lat.quantile(0.5)),
            "p99": _ms(lat.quantile(0.99)),
            "max": _ms(lat.max()),
        }

    def publish_ms(self) -> dict[str, float | None]:
        pub = self.publish
        return {"p50": _ms(pub.quantile(0.5)), "p99": _ms(pub.quantile(0.99))}
