"""The state the default mode's EKF is built on (navd/filter/ekf.py): the nominal state,
its error covariance in metres, and the algebra between them.

    nominal  x = (lat, lon, c_n, c_e, b, s, o_n, o_e)
    error   dx = (dn, de, dc_n, dc_e, db, ds, do_n, do_e)
             metres, m/s, radians, scale, metres

Its parts, as AP_NavEKF3 splits its core: this state; range fusion, re-acquisition
and the relinearised window (navd/filter/ekf_ranges.py, navd/filter/relinearise.py);
prediction, GPS fusion and the outputs (navd/filter/ekf.py).
"""

from __future__ import annotations

import math

import numpy as np

from navd import geodesy
from navd.filter.common import History
from navd.filter.consider import CurrentConsider
from navd.filter.ekf_step import Noise
from navd.filter.tide import TidePrediction
from navd.filter.track import RecentTrack
from navd.settings import NoiseConfig

N_STATES = 8
# Recent ranges the re-acquisition fit looks at, and the dead-reckoned track kept to
# place them (also the round-trip geometry of each range).
WINDOW_S = 300.0
# the time constant of the calibration Jacobian's running mean: half the window, so that
# it weighs the legs the fit saw (opposite legs cancel a heading bias's effect)
CAL_MEAN_S = 0.5 * WINDOW_S


class EkfCore:
    def __init__(self, noise: NoiseConfig, max_current_mps: float) -> None:
        self.noise = noise
        self.max_current = max_current_mps
        self.x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
        self.P = np.eye(N_STATES)
        # the beacon whose reported-position error the offset states track, and its model
        self.primary: str | None = None
        self._off_std = 0.0
        self._off_tau = math.inf
        self.initialised = False
        self.history = History()
        self.t_anchor = 0.0  # when the position was last pinned (GPS, re-acquisition)
        # what a faster-changing current would add to the published covariance (none
        # unless the owner sets one: navd/filter/bank.py's uncalibrated belief)
        self.consider: CurrentConsider | None = None
        # the crew's tidal prediction, a known change of the current (navd/filter/tide.py;
        # none unless the owner sets one), and the stream it last put into the state
        self.tide: TidePrediction | None = None
        self._tide_v: tuple[float, float] | None = None
        self._tide_clock: float | None = None  # the prediction's clock when _tide_v was read
        self.t = 0.0
        self.track = RecentTrack(WINDOW_S)
        # how the water-relative velocity (north, east) moves with heading bias and speed
        # scale (F's position-calibration block over dt), averaged over about the window
        # the re-acquisition fits (row-major: dvn/db, dvn/ds, dve/db, dve/ds)
        self.dv_dcal = [0.0, 0.0, 0.0, 0.0]
        # running totals over the steps, of the time and of what the transitions add
        # (navd/filter/range_biases.py's Path): the transition over any interval, in sums
        self.path = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        # the step's transition and process noise, filled in place by predict
        # (navd/filter/ekf_step.py), and the noise model as that step takes it
        self._F = np.eye(N_STATES)
        self._Q = np.zeros((N_STATES, N_STATES))
        self._step_noise: Noise = (
            noise.speed_std_mps,
            math.radians(noise.heading_std_deg),
            noise.input_corr_s,
            noise.current_walk_mps_per_sqrt_s,
            math.radians(noise.heading_bias_walk_deg_per_sqrt_s),
            noise.speed_scale_walk_per_sqrt_s,
        )

    def keep_history(self) -> None:
        self.history.enabled = True

    def close_history(self) -> None:
        self.history.close()

    def _tide_at(self, t: float) -> tuple[float, float] | None:
        """The crew's predicted stream at ``t``; None without one, or without its clock."""
        return self.tide.velocity(t) if self.tide is not None else None

    def _follow_tide(self, t: float) -> None:
        """Move the current by the predicted stream's change since it was last put in
        (``t``: the middle of the step about to be taken, where the step reads the
        current).  The first prediction, the first after a restart and the first after
        its clock was set again (the GPS receiver's UTC, navd/filter/navigator.py) are only
        noted: the state then already holds the current there, as the data taught it."""
        v = self._tide_at(t)
        if v is None or self.tide is None:
            return
        clock = self.tide.offset_s
        last = self._tide_v if clock == self._tide_clock else None
        self._tide_v, self._tide_clock = v, clock
        if last is not None:
            self.x[2] += v[0] - last[0]
            self.x[3] += v[1] - last[1]

    def predicted_current(self) -> tuple[float, float]:
        """The current's prior mean now (north, east, m/s): the crew's tidal prediction
        where one is followed, else still water."""
        return self._tide_at(self.t) or (0.0, 0.0)

    def _limit_current(self) -> None:
        """Hold the current to what water can do at this site (``max_current_mps``)."""
        speed = math.hypot(float(self.x[2]), float(self.x[3]))
        if speed > self.max_current:
            self.x[2:4] *= self.max_current / speed

    def _apply(self, dx: np.ndarray, hd: float) -> None:
        self.x = self.state_apply(self.x, dx, hd)

    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        e, n, _ = geodesy.enu_offset(b[0], b[1], 0.0, a[0], a[1], 0.0)
        d: np.ndarray = a - b
        d[0], d[1] = n, e
        return d

    def state_apply(self, x: np.ndarray, dx: np.ndarray, hd: float = 0.0) -> np.ndarray:
        y: np.ndarray = x + dx
        y[0], y[1] = geodesy.offset_position(float(x[0]), float(x[1]), dx[0], dx[1], hd)
        return y
