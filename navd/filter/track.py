"""The dead-reckoned track behind the range filter: how far the vehicle has moved
since any moment of the last few minutes.

A range is a round trip: the request left from where the vehicle was at the ping
and the reply reached it later, and a reply may complete after the filter has
stepped past it.  Both ends are found from the present estimate by undoing the
motion since them (navd/filter/ekf_ranges.py), so the track is kept as cumulative
north/east displacement at each filter step.
"""

from __future__ import annotations

import bisect
from collections import deque


class RecentTrack:
    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._t: deque[float] = deque()
        self._ne: deque[tuple[float, float]] = deque()
        self._n = 0.0
        self._e = 0.0

    def step(self, t: float, dn: float, de: float) -> None:
        """The step ending at ``t`` moved ``dn`` m north and ``de`` m east."""
        self._n += dn
        self._e += de
        self._t.append(t)
        self._ne.append((self._n, self._e))
        oldest = t - self.seconds
        ts = self._t
        while ts[0] < oldest:  # never empty: t itself was appended
            ts.popleft()
            self._ne.popleft()

    def displacement_since(self, t0: float) -> tuple[float, float]:
        """Dead-reckoned north/east displacement from ``t0`` to now."""
        ts = self._t
        if not ts or t0 >= ts[-1]:
            return 0.0, 0.0
        i = bisect.bisect_left(ts, t0)
        if i == 0:
            n0, e0 = self._ne[0]
        else:
            # the step ending at ts[i] covered (ts[i-1], ts[i]]: interpolate inside it
            ta, tb = ts[i - 1], ts[i]
            (na, ea), (nb, eb) = self._ne[i - 1], self._ne[i]
            w = (t0 - ta) / (tb - ta) if tb > ta else 1.0
            n0, e0 = na + w * (nb - na), ea + w * (eb - ea)
        return self._n - n0, self._e - e0
