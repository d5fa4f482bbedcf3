"""Range noise beyond the config's, learnt from the ranges: never less than the config says.

The config's ``range_std_m`` is a prior like the calibration's, taken from another
site's trials (Fulton's 3 m at 12 kHz over kilometres, seed 003; Techy et al. measured
1.0 m, seed 004).  Ranges noisier than it make the filter sure of a place they do not
give: on a net of surveyed transponders whose ranges are 1.5 to 3 times noisier than
the config says, the truth left the 95 % ellipse a third of the time (BENCHMARKS.md,
"Ranges noisier than the config says").  So the filter learns what variance the ranges
carry beyond the config's, by covariance matching (Mehra 1972), and adds it to each
range's.

It is learnt from the difference of two successive accepted residuals of one beacon, not
from each residual alone.  A consistent filter's innovations are white, so that
difference's variance is the sum of the two innovation variances.  A filter whose state
is off (a current its priors did not allow for) sees residuals that share a sign from
one range to the next: differencing takes that shared part out, so it is not blamed on
the ranges, which would make the filter trust them less just when it needs them (the
bank's beliefs and the re-acquisition answer that: navd/filter/bank.py).  Both residuals
passed the gate, which cuts a normal residual's tails at ``sqrt(chi2)`` sigma short and
``sqrt(chi2_long)`` long, so the difference is judged against the truncated normal's
variance, and a noise much wider than modelled is learnt in steps: each step widens the
gate, and the estimate stops where the residuals fit it.  Replies the gate refused between
the two do not break the pair: on nets whose ranges were noisier than the config said,
pairs of neighbours alone were fewer and showed less, learnt nothing for minutes, and
left the nets' ellipses too narrow (BENCHMARKS.md, "Tried, not kept: a refusal breaks the pair").

Only ever more than the config's: ranges quieter than the config says leave the filter
as it was (its ellipse wider than its error, and ``navd report`` says so), since what
makes the innovations small may as well be a wide process model as quiet ranges
(BENCHMARKS.md, "the ranges' own noise learnt from their innovations").
"""

from __future__ import annotations

import math

# What the pairs say is averaged over _MEMORY of them, forgotten beyond, starting from a
# consistent filter's worth _PRIOR_PAIRS: a site's noise changes with range and weather
# over an hour, not from one reply to the next.
_PRIOR_PAIRS = 10.0
_MEMORY = 60.0
# the most it may add, in units of the config's range variance: ranges ten times
# noisier than the config says are a wrong config, not weather
_MAX_RATIO = 100.0
# The gate hides most of a noise much wider than the innovation variance (what passes
# looks uniform over the gate), so one look can tell at most this much wider; the wider
# gate then shows the rest.
_MIN_U = 0.5
_MAX_U = 10.0
# u to a part in 1e12, far below what the pairs can tell; the steps only bound a loop
# the Illinois step ends in about twelve
_SOLVE_TOL = 1e-12
_SOLVE_STEPS = 100


def _phi(z: float) -> float:
    return math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def _cdf(z: float) -> float:
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def truncated_difference_variance(short_sigma: float, long_sigma: float) -> float:
    """The variance of the difference of two independent unit normals each kept only
    between ``-short_sigma`` and ``long_sigma`` (Johnson, Kotz and Balakrishnan 1994,
    13.10): twice the truncated variance."""
    a, b = -short_sigma, long_sigma
    z = _cdf(b) - _cdf(a)
    if not z > 0.0:
        return 0.0
    mean = (_phi(a) - _phi(b)) / z
    second = 1.0 + (a * _phi(a) - b * _phi(b)) / z
    return 2.0 * max(second - mean * mean, 0.0)


class RangeNoise:
    """The variance each range carries beyond the config's, from the ranges themselves."""

    def __init__(self, config_var: float, gate_chi2: float, gate_chi2_long: float) -> None:
        self.max_var = _MAX_RATIO * max(config_var, 0.0) if math.isfinite(config_var) else 0.0
        self._short = math.sqrt(gate_chi2) if gate_chi2 > 0.0 else 0.0
        self._long = math.sqrt(gate_chi2_long) if gate_chi2_long > 0.0 else 0.0
        # forgotten sums over the pairs: their weight, their differences squared over the
        # sum of their innovation variances, that variance's half, the extra it held
        self._sums = (0.0, 0.0, 0.0, 0.0)
        self.extra_var = 0.0
        self._last: dict[str, tuple[float, float]] = {}  # beacon: residual, its variance

    def _ratio(self, u: float) -> float:
        """A pair's expected difference squared over its innovation variances' sum when the
        true variance is the model's over ``u^2``, through the gate."""
        return 0.5 * truncated_difference_variance(self._short * u, self._long * u) / (u * u)

    def _u_showing(self, rho: float) -> float:
        """The u in [_MIN_U, _MAX_U] whose :meth:`_ratio` is ``rho`` (the ratio falls as u
        grows), by regula falsi with the Illinois step (Dowell and Jarratt 1971): a dozen
        evaluations where bisection to the same 1e-11 takes forty, and every accepted
        range asks."""
        lo, hi = _MIN_U, _MAX_U
        f_lo, f_hi = self._ratio(lo) - rho, self._ratio(hi) - rho
        if not f_lo > 0.0:
            return lo
        if not f_hi < 0.0:
            return hi
        side = 0
        for _ in range(_SOLVE_STEPS):
            u = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            f = self._ratio(u) - rho
            if f > 0.0:
                lo, f_lo = u, f
                if side > 0:
                    f_hi *= 0.5  # the same end kept twice: halve the other's pull
                side = 1
            elif f < 0.0:
                hi, f_hi = u, f
                if side < 0:
                    f_lo *= 0.5
                side = -1
            else:
                return u
            if hi - lo <= _SOLVE_TOL * hi:
                break
        return 0.5 * (lo + hi)

    def forget_last(self) -> None:
        """The estimate moved by more than a range does (a fix, a re-acquisition): the
        residuals before it are not the next one's neighbours."""
        self._last.clear()

    def accepted(self, beacon: str, residual: float, s: float) -> None:
        """A range fused with ``residual`` and innovation variance ``s`` (with the extra
        variance as it was)."""
        if not (math.isfinite(residual) and math.isfinite(s) and s > 0.0):
            return
        prev = self._last.get(beacon)
        self._last[beacon] = (residual, s)
        if prev is None or not (self._short > 0.0 and self._long > 0.0):
            return
        r0, s0 = prev
        keep = 1.0 - 1.0 / _MEMORY
        n, rho, half, extra = self._sums
        if n == 0.0:  # the prior: a consistent filter at this innovation variance
            n, rho, half = _PRIOR_PAIRS, _PRIOR_PAIRS * self._ratio(1.0), _PRIOR_PAIRS * s
        d = residual - r0
        ratio = d * d / (s + s0)
        self._sums = (
            keep * n + 1.0,
            keep * rho + ratio,
            keep * half + 0.5 * (s + s0),
            keep * extra + self.extra_var,
        )
        self._learnt()

    def _learnt(self) -> None:
        n, rho, half, extra = self._sums
        if not (n > 0.0 and all(map(math.isfinite, self._sums))):
            self._sums, self.extra_var = (0.0, 0.0, 0.0, 0.0), 0.0
            return
        rho, s, held = rho / n, half / n, extra / n
        u = self._u_showing(rho)
        total = s / (u * u)  # the innovation variance the ranges show
        # never below the config's: quieter ranges than it says leave it as it is
        self.extra_var = min(max(total - (s - held), 0.0), self.max_var)

    def held(self) -> tuple[float, float, float, float]:
        """The forgotten sums, as a checkpoint holds them."""
        return self._sums

    def resume(self, held: tuple[float, ...] | None) -> None:
        """A restart goes on from the checkpoint's sums: the water's noise does not leave
        with the process.  Sums that cannot be are none."""
        self._sums, self.extra_var = (0.0, 0.0, 0.0, 0.0), 0.0
        self._last.clear()
        if held is None or len(held) != 4 or not all(math.isfinite(v) for v in held):
            return
        n, rho, half, extra = held
        if n > 0.0 and rho >= 0.0 and half > 0.0 and extra >= 0.0:
            self._sums = (n, rho, half, extra)
            self._learnt()
