"""Range fusion for the default mode's EKF: the round trip's geometry, the gate, and
re-acquisition from consistent evidence.

* Range geometry of the round trip: the request left at ``t_ping`` from where the
  vehicle was then and the reply reached it at ``t``; the predicted range is the mean
  of the out and back legs, the ping end found by undoing the dead-reckoned motion
  since ``t_ping`` (navd/filter/track.py), with its dependence on the current.
* Innovation gate on nu^2 / S (chi-square, one degree of freedom) instead of the
  thesis' one-sigma radius, tighter for ranges that read long (multipath only
  lengthens a path).  The gate follows the covariance (seed 003, 4.2.4), so a filter
  that has dead reckoned for long accepts wider.
* Re-acquisition from consistent evidence: when ``reacquire_after`` of the last
  ``2 * reacquire_after`` ranges were rejected, a robust fit over the recent
  ranges (``navd/filter/reacquire.py``) looks for the position and current
  correction most of them agree on.  Only such a correction is applied, with the
  fit's covariance; a burst of mutually inconsistent long replies finds none and
  changes nothing.  The current it learns is bounded by ``max_current_mps``.
* Relinearisation: after each accepted range, the last ``relinearise_ranges`` of them
  are solved again together, each linearised where the later ones put the vehicle
  (navd/filter/relinearise.py), since one beacon says nothing across its line of sight
  and the estimate that chose each range's direction may have been off across it.
* The range expected over the filter's uncertainty, to second order (its mean lies
  beyond the range from the mean position when the position is unsure across the line
  of sight), in the gate and the update alike.
* The beacon's reported-position error: the first beacon heard has its own states
  (``o_n, o_e``); others add their position error to the range variance.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from navd import geodesy
from navd.filter import reacquire, relinearise
from navd.filter.common import HUBER_K, GateDecision, RangeMeas, joseph_update
from navd.filter.ekf_core import N_STATES, WINDOW_S, EkfCore
from navd.filter.integrity import chi2_quantile
from navd.filter.range_biases import RangeBiases
from navd.filter.range_noise import RangeNoise
from navd.filter.relinearise import LineOfSight
from navd.settings import NoiseConfig

_WINDOW_RANGES = 12
_MIN_SUPPORT = 6  # ranges that must agree on a re-acquisition
_REACQUIRED_STD_M = 200.0  # a fit looser than this leaves the estimate as it is
_LONG_MEMORY = 100.0  # ranges over which how often replies read long is forgotten
_RELIN_RANGES = 30  # accepted ranges the relinearisation solves together (within WINDOW_S)
_RELIN_PASSES = 3
_RELIN_TOL_M = 0.5  # linearisation points that move less than this are where they belong


@dataclass(slots=True)
class _Outage:
    """The primary beacon predicted from one report: the offset states as they were when
    its first prediction came, to be resumed when it ends."""

    origin: float  # the time of the report it is extrapolated from
    t: float
    x: np.ndarray  # the offset's mean and covariance then
    P: np.ndarray
    std_m: float = 0.0  # the prediction's largest std since


def _positive_definite(P: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True


class RangeFusion(EkfCore):
    def __init__(
        self,
        noise: NoiseConfig,
        gate_chi2: float,
        gate_chi2_long: float,
        reacquire_after: int,
        max_current_mps: float = 2.0,
        relinearise_ranges: int = _RELIN_RANGES,
        sound_speed_rel_std: float = 0.0,
    ) -> None:
        """``relinearise_ranges``: the accepted ranges solved again together after each
        (1: none, the plain EKF); ``sound_speed_rel_std``: the configured sound speed's
        one-sigma error as a fraction of it (0: none allowed for)."""
        super().__init__(noise, max_current_mps)
        self.sound_speed_rel_std = sound_speed_rel_std
        # the ranges' scale error (the configured sound speed's) and the surveyed
        # transponders' position errors, estimated beside the filter
        self.biases = RangeBiases(sound_speed_rel_std)
        # what the ranges carry beyond the config's noise (never less than it)
        self.range_noise = RangeNoise(noise.range_std_m**2, gate_chi2, gate_chi2_long)
        # the most extra range variance the biases' information has been weighed at
        self._fused_extra = 0.0
        self.gate_chi2 = gate_chi2
        self.gate_chi2_long = gate_chi2_long
        self.reacquire_after = reacquire_after
        # recent gate decisions: (accepted, residual); see _reacquire
        self._recent: deque[tuple[bool, float]] = deque(maxlen=2 * reacquire_after)
        self.reacquisitions = 0
        # whether a re-acquisition keeps the current this filter knows, its covariance, or
        # allows more (reacquire._drift_prior): the bank's uncalibrated belief does not
        # trust a current it learnt beside a calibration the ranges are still finding
        self.reacquire_trusts_current = True
        # how often replies read long past the gate here (a site's reflectors), as the
        # forgotten sums of that indicator and of the ranges (see reacquire.find); the
        # refusals of a streak are left out, since a drifted estimate refuses them too
        self._long_refused = (0.0, 0.0)
        self.reacquire_refused = 0  # rejection streaks the recent ranges did not explain
        self._outage: _Outage | None = None  # while the primary beacon is predicted
        self._window: deque[tuple[RangeMeas, bool]] = deque(maxlen=_WINDOW_RANGES)
        self.last_nis = math.nan  # normalised innovation squared of the last range
        self.last_s = math.nan  # and its innovation variance (m^2)
        # the share of the last range's residual its update moves the estimate by along
        # its line of sight (the prior's variance there over the residual's): near 1, that
        # range alone placed the estimate, and nothing yet says it was not a reflection
        self.last_pull = math.nan
        # NIS of the last accepted ranges, and the 99 % bound of their sum (chi-square)
        self._nis: deque[float] = deque(maxlen=2 * reacquire_after)
        self._nis_limit = chi2_quantile(0.99, 2 * reacquire_after)
        # the accepted ranges the relinearisation looks back over, as they were fused
        self.relinearise_ranges = max(1, relinearise_ranges)
        self._steps: deque[relinearise.Step] = deque(maxlen=self.relinearise_ranges)
        self.relinearised = 0  # ranges after which the window was solved again

    def _forget_ranges(self, biases_too: bool = True) -> None:
        """A fix or a re-acquisition pinned the estimate: ranges before it say nothing
        it does not, and the considers' errors (navd/filter/consider.py) start again, as
        does what the range biases did to the estimate (navd/filter/range_biases.py); but
        not after a GPS fix, which carries that through its gains."""
        if self.consider is not None:
            self.consider.reset(self.t)
        if biases_too:
            self.biases.reset(self.path)
        self._recent.clear()
        self._nis.clear()
        self._window.clear()
        self._steps.clear()
        self.range_noise.forget_last()

    def move_to(self, x: np.ndarray, grow: np.ndarray) -> None:
        """Take another filter's mean, this one's covariance grown by ``grow`` (the bank
        gives the move's own spread: navd/filter/bank.py).  The ranges before it are
        forgotten, as after a re-acquisition."""
        self.x = x.copy()
        self.P = self.P + grow
        self._forget_ranges()
        self.history.correct(self.x.copy(), self.P.copy())

    def predicted_range(self, m: RangeMeas) -> tuple[float, np.ndarray]:
        """Mean of the out and back legs of the round trip, and its Jacobian.

        The filter may already be past ``m.t`` (a reply completes only after its
        location line): both ends are found by undoing the dead-reckoned motion
        since them, so a late range is fused at its own time.
        """
        r, H, _ = self._line_of_sight(m)
        return r, H

    def range_moments(self, m: RangeMeas) -> tuple[float, float]:
        """The range's expected value and variance (less its own noise) over the filter's
        uncertainty, to second order: what the gate and the update take."""
        r, H, sight = self._line_of_sight(m)
        bias, var2 = self._second_order(r, H, sight)
        return r + bias, float(H @ self.P @ H) + var2

    def _line_of_sight(self, m: RangeMeas) -> tuple[float, np.ndarray, LineOfSight]:
        lat, lon = float(self.x[0]), float(self.x[1])
        dn_p, de_p = self.track.displacement_since(m.t_ping)
        dn_b, de_b = self.track.displacement_since(m.t)
        lat_p, lon_p = geodesy.offset_position(lat, lon, -dn_p, -de_p, m.vehicle_hd)
        lat_b, lon_b = geodesy.offset_position(lat, lon, -dn_b, -de_b, m.vehicle_hd)
        tracked = m.beacon == self.primary
        b_lat, b_lon = m.beacon_lat, m.beacon_lon
        if tracked:
            # where the beacon really is: its report corrected by the estimated offset
            b_lat, b_lon = geodesy.offset_position(
                b_lat, b_lon, float(self.x[6]), float(self.x[7]), m.beacon_hd
            )
        r_back, gn_b, ge_b = geodesy.range_and_gradient(
            lat_b, lon_b, m.vehicle_hd, b_lat, b_lon, m.beacon_hd
        )
        r_out, gn_o, ge_o = geodesy.range_and_gradient(
            lat_p, lon_p, m.vehicle_hd, b_lat, b_lon, m.beacon_hd
        )
        # each end lies (now - its time) seconds of current drift behind the estimate
        lag_o = max(0.0, self.t - m.t_ping)
        lag_b = max(0.0, self.t - m.t)
        H = np.zeros(N_STATES)
        H[0] = 0.5 * (gn_o + gn_b)
        H[1] = 0.5 * (ge_o + ge_b)
        H[2] = -0.5 * (lag_o * gn_o + lag_b * gn_b)
        H[3] = -0.5 * (lag_o * ge_o + lag_b * ge_b)
        if tracked:
            # moving the beacon moves the range like moving the vehicle the other way
            H[6] = -H[0]
            H[7] = -H[1]
        sight = LineOfSight(r_out, gn_o, ge_o, r_back, gn_b, ge_b, lag_o, lag_b, tracked)
        return 0.5 * (r_out + r_back), H, sight

    def _second_order(self, r: float, H: np.ndarray, sight: LineOfSight) -> tuple[float, float]:
        """The second-order terms of the range over the filter's uncertainty (the
        second-order EKF: Bar-Shalom, Li and Kirubarajan 2001, section 10.3.2): its mean
        lies ``tr(M P) / 2`` beyond the range from the mean position and its variance
        grows by ``tr(M P M P) / 2``, where ``M = (I - g g^T) / r`` is the Hessian of the
        slant range in the horizontal position (``g`` the range's gradient there) and ``P``
        the covariance of the vehicle's position relative to the beacon: position, the
        current's drift since the ping, the tracked beacon's offset.

        Why: a position unsure by ``s`` across the line of sight makes every range read
        about ``s^2 / 2r`` long; a first-order filter takes the true ranges for multipath,
        gates them, and its cross-range uncertainty never catches up with its error.
        """
        g = H[:2]
        lag = 0.5 * (sight.lag_ping + sight.lag_reply)
        A = np.zeros((2, N_STATES))
        A[0, 0] = A[1, 1] = 1.0
        A[0, 2] = A[1, 3] = -lag
        if sight.tracked:
            A[0, 6] = A[1, 7] = -1.0
        Pp = A @ self.P @ A.T
        M = (np.eye(2) - np.outer(g, g)) / max(r, 1.0)
        MP = M @ Pp
        bias = 0.5 * float(np.trace(MP))
        var2 = 0.5 * float(np.trace(MP @ MP))
        if not (math.isfinite(bias) and math.isfinite(var2)):
            return 0.0, 0.0
        return bias, var2

    def _floor_along_sight(self, H: np.ndarray, std_m: float) -> None:
        """Keep the position's variance along the line of sight to a beacon whose
        position error is not a state at least that error's variance.

        Such an error is counted as range noise, as if each reply's were new; but a
        surveyed transponder's is the same for every reply (a boat's GPS, for a minute or
        two).  Averaged over many replies as white noise it would shrink below what the
        ranges can say: the vehicle is never known better, along that line, than the
        beacon it ranges to."""
        g = H[:2]
        norm = math.hypot(float(g[0]), float(g[1]))
        if not (norm > 0.0 and std_m > 0.0):
            return
        a = np.zeros(N_STATES)
        a[:2] = g / norm
        short = std_m * std_m - float(a @ self.P @ a)
        if short > 0.0:
            self.P = self.P + short * np.outer(a, a)

    def carry_considered_walk(self) -> None:
        """From now on the current walks in the filter's own gains as fast as its consider
        allowed for, and the error the consider followed joins the covariance: ranges that
        see the water change in every direction (a second, surveyed transponder) keep up
        with it rather than lag behind."""
        c = self.consider
        if c is None:
            return
        self.P[:4, :4] += c.covariance(self.t)
        speed, heading, corr, walk, bias_walk, scale_walk = self._step_noise
        self._step_noise = (speed, heading, corr, math.hypot(walk, c.walk), bias_walk, scale_walk)
        self.consider = None
        self.history.widen(self.P.copy())

    def _track_beacon(self, m: RangeMeas) -> None:
        """Adopt the first beacon heard as the one whose position error is estimated."""
        if self.primary is not None or m.beacon_position_std_m <= 0.0:
            return
        self.primary = m.beacon
        self._off_std = m.beacon_position_std_m
        self._off_tau = m.beacon_position_corr_s
        if self._outage is None:  # else a restart's (resume_outage): the offset holds its error
            self.P[6, 6] = self.P[7, 7] = self._off_std**2
        self.history.widen(self.P.copy())

    def _extrapolation(self, m: RangeMeas) -> float:
        """The part of ``m``'s noise that the offset states take on: the error of a tracked
        beacon predicted through its location line's outage.

        The prediction is one extrapolation from the boat's last reports, and its error
        (mostly the velocity's, times the time since) is every reply's of the outage.
        Counted as each range's own noise, a few minutes of replies average it away: the
        vehicle ends up sure of where it is from a boat that was not there, and when the
        reports return, the ranges that disagree along the line of sight are refused
        until one passes the gate and drags the estimate across it.  So through an
        outage the offset, the error of the beacon's position, holds it too: its variance
        grows as the extrapolation's does.  When the reports return (or the beacon is
        extrapolated from a newer one), what the offset learnt of the extrapolation is no
        longer the beacon's error, and the offset is again what it was before the outage,
        carried on as its own error wanders.
        """
        if m.beacon != self.primary:
            return 0.0
        pred = m.beacon_predicted_std_m if math.isfinite(m.beacon_predicted_std_m) else 0.0
        origin = m.beacon_predicted_from
        o = self._outage
        changed = o is not None and not (pred > 0.0 and (origin == o.origin or math.isnan(origin)))
        if o is not None and changed:  # reported again, or extrapolated from a newer report
            self._outage = None
            phi = math.exp(-max(self.t - o.t, 0.0) / self._off_tau)
            self.x[6:8] = phi * o.x
            self.P[6:8, :] = 0.0
            self.P[:, 6:8] = 0.0
            self.P[6:8, 6:8] = phi * phi * o.P + (1.0 - phi * phi) * self._off_std**2 * np.eye(2)
            self._steps.clear()  # the window's ranges cannot be solved across the change
        if pred > 0.0:
            if self._outage is None:
                self._outage = _Outage(origin, self.t, self.x[6:8].copy(), self.P[6:8, 6:8].copy())
            grown = max(pred * pred - self._outage.std_m**2, 0.0)
            self._outage.std_m = max(pred, self._outage.std_m)
            self.P[6, 6] += grown
            self.P[7, 7] += grown
            changed = True
        if changed:
            self.history.widen(self.P.copy())
        return pred

    def outage_held(self) -> tuple[float, ...] | None:
        """The outage under way as a checkpoint holds it (``Held.outage``), or None."""
        o = self._outage
        if o is None:
            return None
        (pnn, pne), (_, pee) = o.P.tolist()
        return (o.origin, o.t, float(o.x[0]), float(o.x[1]), pnn, pne, pee, o.std_m)

    def resume_outage(self, held: tuple[float, ...] | None) -> None:
        """A restart in the middle of an outage: the offset states hold its error already
        (the checkpoint's covariance), and when it ends they are again what they were
        before it.  Without this the restart would take the outage to start then, and
        keep what the offset learnt of the prediction as the beacon's own error once the
        reports return.  Anything but a well-formed outage is none."""
        self._outage = None
        if held is None or len(held) != 8 or not all(math.isfinite(v) for v in held):
            return
        origin, t, xn, xe, pnn, pne, pee, std = held
        P = np.array([[pnn, pne], [pne, pee]])
        if std < 0.0 or pnn < 0.0 or pee < 0.0 or pne * pne > pnn * pee:
            return
        self._outage = _Outage(origin, t, np.array([xn, xe]), P, std)

    def _surveyed(self, m: RangeMeas) -> bool:
        """Whether ``m``'s beacon is a surveyed one (an error that does not wander) that the
        offset states do not track: the range biases carry its error."""
        if m.beacon == self.primary or not m.beacon_position_std_m > 0.0:
            return False
        return math.isinf(m.beacon_position_corr_s)

    def _unbiased(self, m: RangeMeas) -> RangeMeas:
        """``m`` with the biases as estimated taken out: the range at the water's sound
        speed, the beacon where its surveyed position's error puts it."""
        rng = self.biases.corrected(m.range_m)
        off = self.biases.offset(m.beacon)
        if off is None:
            return replace(m, range_m=rng)
        lat, lon = geodesy.offset_position(m.beacon_lat, m.beacon_lon, off[0], off[1], m.beacon_hd)
        return replace(m, range_m=rng, beacon_lat=lat, beacon_lon=lon)

    def range_update(self, m: RangeMeas) -> GateDecision:
        self._track_beacon(m)
        surveyed = self._surveyed(m)
        if surveyed:
            self.biases.surveyed(m.beacon, m.beacon_position_std_m)
            self.carry_considered_walk()  # a net: this filter now sees the water everywhere
        m = self._unbiased(m)
        extrapolated = self._extrapolation(m)
        x_prior, P_prior = self.x.copy(), self.P.copy()
        expected, H, sight = self._line_of_sight(m)
        r_var = max(m.std_m**2 - extrapolated**2, 1e-6) + self.range_noise.extra_var
        untracked = m.beacon != self.primary and not surveyed
        if untracked:
            # a wandering error of another beacon's position is not a state: count it as
            # range noise
            r_var += m.beacon_position_std_m**2
        # the range's mean and spread over the filter's uncertainty, not at its mean
        bias, var2 = self._second_order(expected, H, sight)
        expected += bias
        r_var += var2
        residual = m.range_m - expected
        hph = float(H @ self.P @ H)
        S = hph + r_var
        # the gate, the weights and the NIS see the biases' uncertainty as well, which
        # the filter's own covariance does not hold
        c = self.biases.jacobian(m.beacon, expected, H)
        S += self.biases.spread(self.path, H, c)
        chi2 = self.gate_chi2_long if residual > 0.0 else self.gate_chi2
        gate_m = math.sqrt(chi2 * S)
        self.last_s = S
        self.last_nis = residual * residual / S
        self.last_pull = hph / S
        while self._window and m.t - self._window[0][0].t > WINDOW_S:
            self._window.popleft()
        if residual * residual > chi2 * S:
            self._window.append((m, True))
            self._recent.append((False, residual))
            rejected = [r for ok, r in self._recent if not ok]
            if len(rejected) < self.reacquire_after:
                # a refusal among accepted ranges: an outlier, not an estimate gone wrong
                self._count_long(residual > 0.0)
                return GateDecision(False, residual, gate_m, "gate", on_residual=True)
            if self._reacquire(m):
                return GateDecision(False, residual, gate_m, "gate_reacquire", on_residual=True)
            self.reacquire_refused += 1
            return GateDecision(False, residual, gate_m, "gate", on_residual=True)
        self._window.append((m, False))
        self._count_long(False)
        self.range_noise.accepted(m.beacon, residual, S)
        if self.range_noise.extra_var > self._fused_extra:
            # the biases learnt from ranges fused as quieter than they are
            r0 = m.std_m**2
            self.biases.deweight((r0 + self.range_noise.extra_var) / (r0 + self._fused_extra))
            self._fused_extra = self.range_noise.extra_var
        self._nis.append(self.last_nis)
        if len(self._nis) == self._nis.maxlen and sum(self._nis) > self._nis_limit:
            # Accepted, but the recent ranges together say the covariance claims too
            # much (a drifting estimate whose current prior was too small): test for a
            # re-acquisition as after a run of rejections.
            self._nis.clear()
            if self._reacquire(m, min_rejected=0):
                return GateDecision(False, residual, gate_m, "gate_reacquire", on_residual=True)
            self.reacquire_refused += 1
        if residual > HUBER_K * math.sqrt(S):
            # A long reply inside the gate may still be multipath: the gate is wide when
            # the estimate is uncertain.  Weigh it as a Huber M-estimator does, so its
            # pull is that of a k-sigma residual (and its information less): a long
            # outlier cannot drag the estimate, a true range still moves it.
            r_var = residual * math.sqrt(S) / HUBER_K - (S - r_var)
        K, self.P, _ = joseph_update(self.P, H, r_var)
        if self.consider is not None:
            self.consider.update(self.t, K, H)
        # the residual's variance to the filter, with the weight it was fused with
        shift = self.biases.ranged(self.path, K, H, c, residual, hph + r_var)
        self._apply(K * residual, m.vehicle_hd)
        self._limit_current()
        self._relinearise(sight, m, r_var, x_prior, P_prior, m.range_m - bias)
        self._shift(shift, m.vehicle_hd)
        if untracked:
            self._floor_along_sight(H, m.beacon_position_std_m)
        self._recent.append((True, residual))
        self.history.correct(self.x.copy(), self.P.copy())
        return GateDecision(True, residual, gate_m, "ok")

    def _count_long(self, long_refused: bool) -> None:
        keep = 1.0 - 1.0 / _LONG_MEMORY
        hits, n = self._long_refused
        self._long_refused = (keep * hits + long_refused, keep * n + 1.0)

    @property
    def long_refused(self) -> float:
        """The fraction of recent ranges the gate refused as reading long."""
        hits, n = self._long_refused
        return hits / n if n > 0.0 else 0.0

    def long_refused_held(self) -> tuple[float, float]:
        """Its counts as a checkpoint holds them (``Held.long_refused``)."""
        return self._long_refused

    def resume_long_refused(self, held: tuple[float, float] | None) -> None:
        """A restart goes on counting where the checkpoint left off: a site's reflectors
        do not leave with the process.  Counts that cannot be are none."""
        self._long_refused = (0.0, 0.0)
        if held is None or len(held) != 2 or not all(math.isfinite(v) for v in held):
            return
        hits, n = held
        if 0.0 <= hits <= n:
            self._long_refused = (hits, n)

    def _shift(self, shift: np.ndarray, hd: float) -> None:
        """Move the state by what the range biases just learnt did to it
        (navd/filter/range_biases.py); the relinearised window's last state with it."""
        if not shift.any():
            return  # nothing learnt (a scale taken as known, a broken step)
        self._apply(shift, hd)
        self._limit_current()
        if self._steps:
            self._steps[-1].x_post = self.x.copy()

    def _relinearise(
        self,
        sight: LineOfSight,
        m: RangeMeas,
        r_var: float,
        x_prior: np.ndarray,
        P_prior: np.ndarray,
        range_m: float,
    ) -> None:
        """Add the range just fused to the window and solve the window again
        (navd/filter/relinearise.py).  ``range_m`` is the range less its second-order
        part at this prior (see _second_order), so the window's first-order model about
        the states it solves for predicts it."""
        steps = self._steps
        while steps and self.t - steps[0].t > WINDOW_S:
            steps.popleft()
        phi = np.eye(N_STATES)
        qd = np.zeros((N_STATES, N_STATES))
        if steps:
            prev = steps[-1]
            dt = self.t - prev.t
            d = self.state_diff(x_prior, prev.x_post)
            cn, ce, _, scale = prev.x_post[2:6].tolist()
            if not scale > 0.1:
                steps.clear()
                return
            # the filter's transitions multiply to the identity plus their sums: the
            # motion through the water (total less the current's) and its derivatives
            wn, we = float(d[0]) - cn * dt, float(d[1]) - ce * dt
            phi[0, 2] = phi[1, 3] = dt
            phi[0, 4], phi[1, 4] = -we, wn
            phi[0, 5], phi[1, 5] = wn / scale, we / scale
            if self.primary is not None:
                phi[6, 6] = phi[7, 7] = math.exp(-dt / self._off_tau)
            qd = relinearise.transition_noise(phi, prev.P_post, P_prior)
        steps.append(
            relinearise.Step(
                self.t,
                P_prior,
                self.state_diff(self.x, x_prior),
                self.P.copy(),
                phi,
                qd,
                sight,
                range_m,
                r_var,
                x_prior,
                self.x.copy(),
            )
        )
        solved = relinearise.solve(steps, _RELIN_PASSES, _RELIN_TOL_M)
        if solved is None:
            return
        if not _positive_definite(solved[1]):
            # a window whose transitions no longer describe the filter's chain (a state
            # moved outside it) solves to a covariance that is none: keep the filter's
            steps.clear()
            return
        k, self.P = solved
        self.x = self.state_apply(x_prior, k, m.vehicle_hd)
        self._limit_current()
        last = steps[-1]
        last.x_post = self.x.copy()
        last.k = self.state_diff(self.x, x_prior)
        last.P_post = self.P.copy()
        self.relinearised += 1

    def _rays(self) -> list[reacquire.Ray]:
        """The recent ranges seen from the present estimate, for the re-acquisition fit."""
        lat, lon = float(self.x[0]), float(self.x[1])
        rays = []
        for m, rejected in self._window:
            b_lat, b_lon = m.beacon_lat, m.beacon_lon
            sigma2 = m.std_m**2 + m.beacon_position_std_m**2 + self.range_noise.extra_var
            if m.beacon == self.primary:
                b_lat, b_lon = geodesy.offset_position(
                    b_lat, b_lon, float(self.x[6]), float(self.x[7]), m.beacon_hd
                )
            e, n, _ = geodesy.enu_offset(lat, lon, m.vehicle_hd, b_lat, b_lon, m.vehicle_hd)
            dn_p, de_p = self.track.displacement_since(m.t_ping)
            dn_b, de_b = self.track.displacement_since(m.t)
            rays.append(
                reacquire.Ray(
                    (n, e, m.beacon_hd - m.vehicle_hd),
                    (-dn_p, -de_p),
                    (-dn_b, -de_b),
                    max(0.0, self.t - m.t_ping),
                    max(0.0, self.t - m.t),
                    m.range_m,
                    math.sqrt(sigma2),
                    rejected,
                    m.beacon,
                    m.beacon_position_std_m,
                    m.beacon_position_corr_s,
                    m.beacon_predicted_std_m,
                    m.beacon_predicted_from,
                )
            )
        return rays

    def _reacquire(self, m: RangeMeas, min_rejected: int | None = None) -> bool:
        """Move to the correction the recent ranges agree on; False if they do not agree.

        Consecutive rejections mean either the estimate has gone wrong (the seed's
        Chesapeake run: current prior too small, every range rejected) or the ranges
        have (a multipath burst).  Only the first gives ranges that agree with one
        another on a correction.
        """
        J = np.array(self.dv_dcal).reshape(2, 2)
        hyp = reacquire.find(
            self._rays(),
            (float(self.x[2]), float(self.x[3])),
            self.P[:2, :2].copy(),
            self.P[2:4, 2:4].copy(),
            # a drift older than the window would have shown in the ranges before it,
            # which the covariance already holds
            min(max(0.0, self.t - self.t_anchor), WINDOW_S),
            self.max_current,
            _MIN_SUPPORT,
            self.reacquire_after if min_rejected is None else min_rejected,
            _REACQUIRED_STD_M,
            seed=self.reacquisitions * 7919 + self.reacquire_refused,
            scale_var=self.biases.m,
            long_refused=self.long_refused,
            cal_drift_cov=J @ self.P[4:6, 4:6] @ J.T,
            trust_current=self.reacquire_trusts_current,
        )
        if hyp is None:
            return False
        dx = np.zeros(N_STATES)
        dx[:4] = (hyp.d_north, hyp.d_east, hyp.dc_north, hyp.dc_east)
        self._apply(dx, m.vehicle_hd)
        # The fit is now what is known of position and current.  Its current is the
        # mean water-relative velocity the ranges imply over its window, which heading
        # bias and speed scale move as much as the current does (the dead-reckoned track
        # it was fitted along used the estimated calibration): the current's error is the
        # fit's less J times the calibration's error, J the window's mean calibration
        # Jacobian, so it carries the calibration's uncertainty and is correlated with
        # it.  Correlations with the beacon offset are dropped.
        P = self.P.copy()
        P_cal = P[4:6, 4:6].copy()
        P[:4, :] = 0.0
        P[:, :4] = 0.0
        P[:4, :4] = hyp.cov
        P[2:4, 2:4] += J @ P_cal @ J.T
        P[2:4, 4:6] = -J @ P_cal
        P[4:6, 2:4] = P[2:4, 4:6].T
        self.P = 0.5 * (P + P.T)
        self._limit_current()
        self._forget_ranges()
        self.t_anchor = m.t
        self.reacquisitions += 1
        self.history.correct(self.x.copy(), self.P.copy())
        return True
