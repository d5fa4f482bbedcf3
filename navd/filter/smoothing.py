"""What the navigator keeps for the RTS smoother, when asked (``navd replay --smooth``).

Each filter the navigator runs, between restarts, is one segment: its step history
(:class:`navd.filter.common.History`, on disk) and the estimates of its ticks with the
step each was made at.  The estimates go to a temporary file as their serialised
lines, and come back when smoothed: a day's replay keeps a few bytes a tick.

The smoother runs over the filter's chain, its state and covariance.  What the filter's
published covariance holds beside that chain (the range biases' share, the current its
belief considers, the spread between the calibration bank's beliefs) the chain does not
carry, and smoothing cannot take it away: each smoothed estimate keeps it as the filter
published it at that tick.  Only what it adds is kept: the published covariance less the
chain's is not a covariance where the bank publishes the mixture about a belief whose
chain is wider in some direction than the other's, and added to a smoothed covariance
that has shrunk it would leave an ellipse that is no ellipse at all (a tenth to a
quarter of the submerged ticks of a run that refuted its current prior, BENCHMARKS.md).
"""

from __future__ import annotations

import tempfile
from array import array
from collections.abc import Iterator

import numpy as np

from navd.filter import estimate
from navd.filter.common import NavFilter, Smoothable, StateEstimate, psd_part
from navd.filter.smoother import rts_backward
from navd.formats import jsonlines
from navd.schema import Estimate, from_dict, to_dict

_FIELDS = len(StateEstimate.__slots__)


class _Segment:
    def __init__(self, flt: Smoothable) -> None:
        self.filter = flt
        flt.keep_history()
        self.steps = array("q")  # the step each tick's estimate was made at
        # what each tick's published covariance held beside the chain: (nn, ee, ne)
        self.beside = array("d")
        self.lines = tempfile.TemporaryFile()  # noqa: SIM115 - lives as long as the history, closed by close()

    def tick(self, est: Estimate) -> None:
        self.steps.append(len(self.filter.history) - 1)
        f = self.filter
        own = f.estimate_of(f.x, f.P)
        self.beside.extend(
            psd_part(
                est.std_n * est.std_n - own.var_n,
                est.std_e * est.std_e - own.var_e,
                est.cov_ne - own.cov_ne,
            )
        )
        self.lines.write(jsonlines.dumps_line(to_dict(est)).encode())

    def smoothed(self) -> Iterator[Estimate]:
        f = self.filter
        n = len(self.steps)
        values = np.empty((n, _FIELDS))
        j = n - 1
        for k, x, P in rts_backward(f.history, f.state_diff, f.state_apply):
            while j >= 0 and self.steps[j] == k:
                e = f.estimate_of(x, P)
                nn, ee, ne = self.beside[3 * j : 3 * j + 3]
                values[j] = (e.lat, e.lon, e.current_n, e.current_e,
                             e.var_n + nn, e.var_e + ee, e.cov_ne + ne)  # fmt: skip
                j -= 1
            if j < 0:
                break  # no tick before this step: the rest of the pass changes nothing
        self.lines.seek(0)
        for line, row in zip(self.lines, values, strict=True):
            filtered = from_dict(Estimate, jsonlines.loads(line))
            yield estimate.smoothed(filtered, StateEstimate(*row.tolist()))

    def close(self) -> None:
        self.lines.close()
        self.filter.close_history()


class Smoothing:
    """The segments of one run, smoothed in order at the end."""

    def __init__(self) -> None:
        self._segments: list[_Segment] = []
        self._current: _Segment | None = None

    def start(self, flt: NavFilter) -> None:
        """A new filter (the first, or one after a restart): a segment of its own.  A mode
        that cannot be smoothed has none (``navd replay --smooth`` refuses it first)."""
        self._current = _Segment(flt) if isinstance(flt, Smoothable) else None
        if self._current is not None:
            self._segments.append(self._current)

    def tick(self, est: Estimate) -> None:
        if self._current is not None:
            self._current.tick(est)

    def smoothed(self) -> Iterator[Estimate]:
        """Every tick's estimate re-written by the Rauch-Tung-Striebel smoother."""
        for seg in self._segments:
            yield from seg.smoothed()

    def close(self) -> None:
        for seg in self._segments:
            seg.close()
        self._segments = []
        self._current = None
