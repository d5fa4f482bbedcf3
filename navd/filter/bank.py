"""Two range EKFs that differ in what they believe of the calibration, weighed by the ranges.

The config's priors on the current, the compass bias and the speed scale are a
belief, and can be wrong by ten times (a site's current guessed from a chart, an
AHRS calibrated on another boat).  One filter that trusts them, told otherwise by
the ranges, rejects them (its covariance says they cannot be) and stays sure of a
position it has lost.  Grown to take them, it opens its gate to the multipath
replies of a single beacon (BENCHMARKS.md, "Honest uncertainty near the bound").

So the default mode runs both beliefs as a multiple-model bank (Bar-Shalom, Li and
Kirubarajan 2001, 11.6): ``config`` with the config's priors, and ``uncal`` with
them widened to what an uncalibrated vehicle in unknown water has.  Each has its
own gate, Huber weighting and re-acquisition, so neither is dragged by the other.
Each range weighs them by how likely each filter found it, under a likelihood with
an outlier part, so a multipath reply that both refuse is evidence for neither.  A
transition probability per range keeps either belief alive.

The estimate is the config filter's mean with the covariance of the mixture about
it, ``(1 - w) P_c + w (P_u + D + d d^T)``, ``d`` the uncalibrated filter's mean seen
from it and ``w`` its weight until the next range: while the ranges say the config may
be wrong, the published ellipse holds where the other belief puts the vehicle, and
integrity degrades with it.  ``D`` is what water turning like the site's strongest
tide would add to the uncalibrated filter's error (navd/filter/consider.py): one
beacon cannot see a current change across its line of sight, so the belief that
allows for unknown water allows for that too, in its spread but not in its gains.  A
net of surveyed transponders sees the water change in every direction, so once one
other than the tracked beacon replies, the uncalibrated filter carries that walk in its
own gains instead: considered only, its lag behind such water grew without bound (on
a 3-transponder net with the bound's noise model, a published std of 15-37 m against
errors of a metre, BENCHMARKS.md).
The mean is not moved to the mixture's: with one beacon a wrong filter still predicts
the next range well while it sits on the same circle, so a few ranges can give a
diverged ``uncal`` nearly all the weight, and following it made the drawn missions
worse (BENCHMARKS.md).  With a net of two transponders the ellipse holds the other
crossing of their circles too (navd/filter/mirror.py).

Until the config's priors are refuted.  The config filter's own calibration is then
further from them than they allow: its current, heading bias and speed scale, against
the priors with the random walks since the start, past the 99.9 % quantile of
chi-square on their four degrees of freedom.  Such a filter got there by re-acquisitions
that threw its covariance away, not by the ranges weighing against its priors, so the
weight of the ranges says nothing of it, and a dragged filter can sit a kilometre off
on the wrong side of its beacon while still predicting its ranges.  From then on the
bank follows the uncalibrated filter (its mean, its gate decisions, its history for the
smoother, its state for the checkpoint), and says so (``calibration_refuted``).  Its
ellipse is then the mixture's about that mean, but never narrower than the uncalibrated
filter's own: the config belief may still widen it (its mean elsewhere), not narrow it, for
its covariance came of the refuted priors.  Where both beliefs put the vehicle in one
place, the mixture drew the ellipse about that place nearly as narrow as those priors, and
just after a dive, with the heading bias still untested, told the autopilot ``ok`` while
15 m off (BENCHMARKS.md, "A refuted belief's narrowness").  A right config's own
estimate stays well inside its priors, since its posterior is narrower than them.

The uncalibrated belief can also be lost on its own.  Its wide priors let one range that
reads a few metres short just after the dive (the boat's GPS wandering) move its speed
scale by a standard deviation; its error then grows as fast as its spread, every true
reply reads about two of them long of it, and its long-side gate, narrow against
multipath, refuses them all, while its re-acquisitions, which fit position and current
along a track its wrong calibration bends, find nothing for minutes, then a wrong place
(BENCHMARKS.md, "A lost belief moves to the other's mean").  An interacting multiple
model starts each filter at every cycle from a mix of all of them (Bar-Shalom, Li and
Kirubarajan 2001, 11.6), which here would drag each belief by the multipath the other
accepts.  So the bank mixes only once the ranges have given the uncalibrated belief up:
when, for as many ranges in a row as its re-acquisition looks back over (twice
``reacquire_after``), it refuses on its residual a range the config belief accepts,
re-acquires nothing, and is left weighing less than the chance of a switch, it moves to
the config belief's mean, its covariance grown by the move (the outer product of the
difference, the spread an interacting multiple model's mixing adds), so that it still
holds the place it had.  The weights stay as the ranges left them.  The config belief is
never moved to the other's: its covariance is the config's, narrow, and at the other's
place it would be sure of a place it never found, on a circle a wrong filter predicts as
well as a right one (measured in BENCHMARKS.md).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from navd.filter.common import (
    Corrections,
    GateDecision,
    Held,
    History,
    RangeMeas,
    StateEstimate,
    psd_part,
    spread_about,
)
from navd.filter.consider import CurrentConsider
from navd.filter.ekf import RangeEKF
from navd.filter.integrity import chi2_quantile
from navd.filter.lsfix import Fix
from navd.filter.mirror import MirrorTwin
from navd.settings import NoiseConfig

# The uncalibrated belief: the config's priors times _WIDEN (the Monte Carlo's wrong
# priors are 3 to 10 times too small), capped at what a small AUV's sensors and a
# coastal site make plausible.  Its random walks are the config's: with one beacon, a
# wider current walk makes the filter itself inconsistent, and the ranges then give the
# sharper config belief the weight, so the published ellipse loses the truth where the
# config's priors are wrong (measured in BENCHMARKS.md, "The uncalibrated belief's
# current walk").
_WIDEN = 10.0
_MAX_CURRENT_STD_FRACTION = 0.5  # of max_current_mps, per axis
_MAX_BIAS_STD_DEG = 15.0
_MAX_SCALE_STD = 0.25
# A range either came from the filter's model or is an outlier (multipath, a corrupt
# position), spread evenly over the multipath lengths of a coastal site.
_OUTLIER_PROB = 0.3
_OUTLIER_SPREAD_M = 300.0
# The chance per range that the belief that holds has changed.  The ellipse is drawn
# with the weights for the time until the next range, after that chance, so it always
# holds at least a twentieth of the other belief's spread: smaller (0.01, measured) left
# the truth outside it for the minutes the evidence takes to build.
_SWITCH = 0.05
_PRIOR = 0.5  # before any range, neither belief is the likelier
# The water the uncalibrated belief allows for may turn like the site's strongest tide
# (the principal lunar semidiurnal period): its published covariance adds what such a
# stream would beyond the filter's own walk (navd/filter/consider.py); its mean, gates
# and weights keep the config's walk.
M2_PERIOD_S = 12.42 * 3600.0
_CURRENT_LEARNT_S = 600.0
# The config's priors are refuted past this distance of the config filter's calibration
# from them (chi-square, 4 degrees of freedom: current north and east, bias, scale).
_REFUTED_CHI2 = chi2_quantile(0.999, 4)


def uncalibrated_noise(nz: NoiseConfig, max_current_mps: float) -> NoiseConfig:
    """The config's noise with the calibration's priors widened."""

    def wider(v: float, k: float, cap: float) -> float:
        return max(v, min(k * v, cap))

    return replace(
        nz,
        current_init_std_mps=wider(
            nz.current_init_std_mps, _WIDEN, _MAX_CURRENT_STD_FRACTION * max_current_mps
        ),
        heading_bias_init_std_deg=wider(nz.heading_bias_init_std_deg, _WIDEN, _MAX_BIAS_STD_DEG),
        speed_scale_init_std=wider(nz.speed_scale_init_std, _WIDEN, _MAX_SCALE_STD),
    )


def tidal_walk(max_current_mps: float) -> float:
    """The current walk (m/s/sqrt s) that keeps up with a semidiurnal stream as strong as
    the site's strongest: its fastest change, amplitude times 2 pi / T, over the time
    ranges from one beacon take to determine a current (docs/replay.md, "A current that
    changes")."""
    return max_current_mps * 2.0 * math.pi / M2_PERIOD_S * math.sqrt(_CURRENT_LEARNT_S)


def switched(w: float) -> float:
    """A belief's weight after the chance that the belief that holds has changed."""
    return (1.0 - _SWITCH) * w + _SWITCH * (1.0 - w)


def range_likelihood(residual: float, s: float) -> float:
    """p(range | a filter's prediction): Gaussian in the innovation, or an outlier."""
    floor = _OUTLIER_PROB / _OUTLIER_SPREAD_M
    if not (s > 0.0 and math.isfinite(s) and math.isfinite(residual)):
        return floor
    g = math.exp(-0.5 * residual * residual / s) / math.sqrt(2.0 * math.pi * s)
    return (1.0 - _OUTLIER_PROB) * g + floor


class CalibrationBank:
    """The default mode: the config filter and the uncalibrated one, weighed by the ranges."""

    ranges_as_reported = False
    ranges_only_without_gps = False

    def __init__(self, config: RangeEKF) -> None:
        """``config``: a fresh filter with the config's noise; its uncalibrated twin is made
        from it."""
        self.config = config
        self.uncal = config.with_noise(uncalibrated_noise(config.noise, config.max_current))
        self.uncal.reacquire_trusts_current = False
        own = self.uncal.noise.current_walk_mps_per_sqrt_s

        def beyond_own(stream_mps: float) -> float:
            fast = tidal_walk(stream_mps)
            return math.sqrt(max(0.0, fast * fast - own * own))

        self._unknown_walk = beyond_own(config.max_current)
        self.uncal.consider = CurrentConsider(self._unknown_walk)
        # given a crew's tidal prediction, once followed, only what it may miss turns
        # unknown (navd/filter/tide.py)
        tide = config.tide
        self._predicted_walk = (
            beyond_own(min(config.max_current, tide.unknown_mps)) if tide is not None else None
        )
        self.w_uncal = _PRIOR  # the weight of the uncalibrated belief
        self.refuted = False  # the config's priors, by the config filter's own estimate
        self._t0 = 0.0  # when the priors were set (the walks grow them from then)
        self._lost_run = 0  # ranges in a row that said the uncalibrated belief is lost
        # a net of two transponders: the other crossing of their circles
        self.mirror = MirrorTwin()

    @property
    def followed(self) -> RangeEKF:
        """The filter whose mean is published: the config's until its priors are refuted."""
        return self.uncal if self.refuted else self.config

    # what the smoother, the checkpoint and the navigator's gates see: the followed filter
    @property
    def x(self) -> np.ndarray:
        return self.followed.x

    @property
    def P(self) -> np.ndarray:
        return self.followed.P

    @property
    def history(self) -> History:
        return self.followed.history

    def keep_history(self) -> None:
        # both, since the one followed at the end of the mission is the one smoothed
        self.config.keep_history()
        self.uncal.keep_history()

    def close_history(self) -> None:
        self.config.close_history()
        self.uncal.close_history()

    @property
    def initialised(self) -> bool:
        return self.config.initialised

    @property
    def last_nis(self) -> float:
        return self.followed.last_nis

    @property
    def last_pull(self) -> float:
        return self.followed.last_pull

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None:
        self.config.initialise(lat, lon, std_m, t)
        self.uncal.initialise(lat, lon, std_m, t)
        self.w_uncal = _PRIOR
        self.refuted = False
        self._t0 = t
        self._lost_run = 0
        self.mirror.forget()

    def checkpoint(self) -> tuple[np.ndarray, np.ndarray, Held]:
        return self.followed.checkpoint()

    def restore(
        self, x: np.ndarray, P: np.ndarray, grow_m2: float, held: Held | None = None
    ) -> None:
        """A checkpoint: the config filter's state; the uncalibrated belief the same, its
        calibration's covariance scaled as its priors are to the config's (the range
        scale, a beacon outage under way and how often replies read long, both believe
        alike)."""
        self.config.restore(x, P, grow_m2, held)
        a, b = self.config.noise, self.uncal.noise
        k = np.ones(len(x))
        k[2:6] = (
            b.current_init_std_mps / a.current_init_std_mps,
            b.current_init_std_mps / a.current_init_std_mps,
            b.heading_bias_init_std_deg / a.heading_bias_init_std_deg,
            b.speed_scale_init_std / a.speed_scale_init_std,
        )
        self.uncal.restore(x, P * np.outer(k, k), grow_m2, held)
        self.w_uncal = _PRIOR
        self._lost_run = 0
        self.mirror.forget()  # the side is the checkpoint's, as its estimate says
        # a checkpoint of a refuted config's run holds the uncalibrated filter's
        # calibration, and the next update refutes the priors again
        self.refuted = False

    def _move_uncal(self) -> None:
        """Move the uncalibrated belief to the config belief's mean; its covariance grows
        by the move, so that it still holds the place it had (the mixture's spread, as an
        interacting multiple model mixes); the weights stay what the ranges made them."""
        d = self.uncal.state_diff(self.uncal.x, self.config.x)
        self._lost_run = 0
        if not np.isfinite(d).all():
            return  # a broken state is no mean to move to, nor a spread to grow by
        self.uncal.move_to(self.config.x, np.outer(d, d))

    def _watch_lost(self, dc: GateDecision, du: GateDecision, reacquired: bool) -> None:
        """After a range's evidence: if the uncalibrated belief refused it on its residual
        without re-acquiring, the config belief accepted it, and the uncalibrated one now
        weighs less than the chance of a switch, it is a range nearer lost; a
        re-acquisition's window of them in a row, and it is lost (the module's
        docstring)."""
        if du.accepted or reacquired:
            self._lost_run = 0
        elif du.on_residual and dc.accepted and self.w_uncal < _SWITCH:
            self._lost_run += 1
        if self._lost_run >= 2 * self.config.reacquire_after:
            self._move_uncal()

    def prior_distance2(self) -> float:
        """The config filter's calibration against the config's priors, grown by the
        random walks since they were set: a squared Mahalanobis distance.  The current's
        prior is about the crew's tidal prediction where there is one."""
        nz, x = self.config.noise, self.config.x
        dt = max(0.0, self.config.t - self._t0)
        var_c = nz.current_init_std_mps**2 + nz.current_walk_mps_per_sqrt_s**2 * dt
        var_b = (
            math.radians(nz.heading_bias_init_std_deg) ** 2
            + math.radians(nz.heading_bias_walk_deg_per_sqrt_s) ** 2 * dt
        )
        var_s = nz.speed_scale_init_std**2 + nz.speed_scale_walk_per_sqrt_s**2 * dt
        cn, ce, b, s = (float(v) for v in x[2:6])
        pn, pe = self.config.predicted_current()
        cn, ce = cn - pn, ce - pe
        return (cn * cn + ce * ce) / var_c + b * b / var_b + (s - 1.0) ** 2 / var_s

    def _test_priors(self) -> None:
        # NaN compares false: a broken state refutes nothing
        if not self.refuted and self.prior_distance2() > _REFUTED_CHI2:
            self.refuted = True

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None:
        tide, consider = self.config.tide, self.uncal.consider
        if self._predicted_walk is not None and consider is not None and tide is not None:
            walk = self._predicted_walk if tide.in_use else self._unknown_walk
            consider.set_walk(walk, self.uncal.t)
        self.config.predict(t, dt, heading, speed, hd)
        self.uncal.predict(t, dt, heading, speed, hd)
        self.mirror.predict(t, dt, heading, speed, hd)

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None:
        self.config.gps_update(lat, lon, std_m, hd)
        self.uncal.gps_update(lat, lon, std_m, hd)
        self.mirror.reset()  # the fix says which side
        self._test_priors()

    def range_update(self, m: RangeMeas) -> GateDecision:
        self.mirror.heard(m)
        decision = self.config.range_update(m)
        reacquisitions = self.uncal.reacquisitions
        du = self.uncal.range_update(m)
        lc = range_likelihood(decision.residual_m, self.config.last_s)
        lu = range_likelihood(du.residual_m, self.uncal.last_s)
        # the transition, then the evidence (Bayes' rule over the two beliefs)
        w = switched(self.w_uncal)
        num = w * lu
        den = num + (1.0 - w) * lc
        self.w_uncal = num / den if den > 0.0 and math.isfinite(den) else w
        self._watch_lost(decision, du, self.uncal.reacquisitions > reacquisitions)
        self._test_priors()
        followed = du if self.refuted else decision
        self.mirror.weigh(m, followed.accepted, 2 * self.config.reacquire_after)
        self.mirror.settle(self.followed)
        return followed

    def estimate(self) -> StateEstimate:
        a = self.config.estimate()
        b = self.uncal.estimate()
        # The weight after the evidence says which belief held at the last range; the
        # one until the next range allows the change the model allows per range.  A
        # weight the evidence drove to nearly nothing would otherwise draw the ellipse
        # of one belief alone, from ranges that tested only their line of sight.
        w = switched(self.w_uncal)
        if not self.refuted:
            return self.mirror.mixed(spread_about(a, b, w))
        # the config filter's covariance came of the priors the data refuted: its mean is
        # still a place to hold, its narrowness no evidence (the module's docstring)
        m = spread_about(b, a, 1.0 - w)
        nn, ee, ne = psd_part(b.var_n - m.var_n, b.var_e - m.var_e, b.cov_ne - m.cov_ne)
        return self.mirror.mixed(
            StateEstimate(
                m.lat, m.lon, m.current_n, m.current_e, m.var_n + nn, m.var_e + ee, m.cov_ne + ne
            )
        )

    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate:
        """A state of the followed filter's chain (the smoother's), as that filter gives it."""
        return self.followed.estimate_of(x, P)

    def apply_fix(self, fix: Fix) -> None:
        """Ranges reach this mode one by one; the net's fix only starts it without GPS."""

    def corrections(self) -> Corrections | None:
        c = self.followed.corrections()
        if c is None:
            return None
        # built directly: dataclasses.replace costs more than the rest of a tick's estimate
        return Corrections(
            c.heading_bias,
            c.speed_scale,
            c.beacon_offset_n,
            c.beacon_offset_e,
            self.w_uncal,
            self.refuted,
        )

    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self.followed.state_diff(a, b)

    def state_apply(self, x: np.ndarray, dx: np.ndarray, hd: float = 0.0) -> np.ndarray:
        return self.followed.state_apply(x, dx, hd)
