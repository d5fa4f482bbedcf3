"""Types shared by the filter modes, and the step history the RTS smoother runs over."""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from navd import geodesy

if TYPE_CHECKING:
    from navd.filter.lsfix import Fix

#: A range reading longer than predicted by more than this many sigma weighs as a Huber
#: M-estimator weighs it, its pull that of a k-sigma residual: multipath only lengthens a
#: path.  The filter's update and the re-acquisition's fit both take it.
HUBER_K = 1.5


@dataclass(frozen=True, slots=True)
class RangeMeas:
    """One acoustic range as it reaches a filter, positions in radians, heights as h - depth."""

    t: float  # arrival of the reply
    t_ping: float  # departure of the request
    range_m: float  # one-way range, already corrected to the water's sound speed where wanted
    beacon: str
    beacon_lat: float
    beacon_lon: float
    beacon_hd: float
    vehicle_hd: float
    std_m: float  # range noise
    beacon_position_std_m: float = 0.0  # error of the position the beacon reported
    beacon_position_corr_s: float = 120.0  # its correlation time
    # the part of std_m that is a predicted beacon's extrapolation error, and the time of
    # the report it was extrapolated from: one extrapolation's error is every such range's
    beacon_predicted_std_m: float = 0.0
    beacon_predicted_from: float = math.nan


@dataclass(frozen=True, slots=True)
class GateDecision:
    accepted: bool
    residual_m: float
    gate_m: float
    reason: str  # "ok", "gate", or why the range never reached the test
    # refused on its residual: by the gate, or by the re-acquisition it set off (the
    # residual's sign then says which way the estimate is off)
    on_residual: bool = False


@dataclass(frozen=True, slots=True)
class StateEstimate:
    lat: float  # radians
    lon: float
    current_n: float  # m/s
    current_e: float
    var_n: float  # m^2
    var_e: float
    cov_ne: float


@dataclass(slots=True)
class Step:
    """One prediction interval, as the smoother needs it (state vectors are filter-defined)."""

    t: float
    F: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    x_filt: np.ndarray
    P_filt: np.ndarray


class History:
    """The steps the RTS smoother runs over, as a sequence in time order.

    All but the latest step live in an anonymous temporary file, as raw float64
    records: a day at 10 Hz is 864,000 steps of three covariances, more than an
    ODROID's memory, and the backward pass reads them back a block at a time.  The
    latest stays in memory, since an update or a widened covariance still changes it.
    Reading back gives the very numbers written, so smoothing is unchanged.
    """

    BLOCK = 1024  # steps read back at a time

    def __init__(self) -> None:
        self.enabled = False
        self._file: IO[bytes] | None = None
        self._on_disk = 0
        self._latest: Step | None = None
        self._n = 0  # state dimension, from the first step
        self._block: tuple[int, np.ndarray] | None = None

    def __len__(self) -> int:
        return self._on_disk + (self._latest is not None)

    def __getitem__(self, k: int) -> Step:
        if not 0 <= k < len(self):
            raise IndexError(k)
        if k == self._on_disk:
            assert self._latest is not None
            return self._latest
        start = k - k % self.BLOCK
        if self._block is None or self._block[0] != start:
            self._block = (start, self._read(start, min(self.BLOCK, self._on_disk - start)))
        return self._unpack(self._block[1][k - start])

    def add(self, t: float, F: np.ndarray, x: np.ndarray, P: np.ndarray) -> None:
        if self.enabled:
            if self._latest is not None:
                self._spill(self._latest)
            self._latest = Step(t, F, x, P, x, P)

    def widen(self, P: np.ndarray) -> None:
        """Record covariance added outside a measurement (re-acquisition, a new prior).

        To the smoother it is process noise of the latest step, so it goes into the
        predicted covariance as well as the filtered one.
        """
        s = self._latest
        if self.enabled and s is not None:
            s.P_pred = s.P_pred + (P - s.P_filt)
            s.P_filt = P

    def correct(self, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the filtered state of the latest step after an update."""
        s = self._latest
        if self.enabled and s is not None:
            s.x_filt, s.P_filt = x, P

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
        self._file, self._on_disk, self._latest, self._block = None, 0, None, None

    # -- the file ----------------------------------------------------------------------
    def _spill(self, s: Step) -> None:
        x_pred = np.asarray(s.x_pred, dtype=float)
        if self._file is None:
            self._n = x_pred.size
            self._file = tempfile.TemporaryFile()  # noqa: SIM115 - lives as long as the history, closed by close()
        if self._block is not None:  # read since the last write: back to the end
            self._file.seek(0, 2)
        self._file.write(
            np.concatenate(
                (
                    [s.t],
                    np.asarray(s.F, dtype=float).ravel(),
                    x_pred,
                    np.asarray(s.P_pred, dtype=float).ravel(),
                    np.asarray(s.x_filt, dtype=float),
                    np.asarray(s.P_filt, dtype=float).ravel(),
                )
            ).tobytes()
        )
        self._on_disk += 1
        self._block = None

    def _width(self) -> int:
        n = self._n
        return 1 + 3 * n * n + 2 * n

    def _read(self, start: int, count: int) -> np.ndarray:
        assert self._file is not None
        w = self._width()
        self._file.seek(start * w * 8)
        data = self._file.read(count * w * 8)
        return np.frombuffer(data, dtype=np.float64).reshape(count, w)

    def _unpack(self, row: np.ndarray) -> Step:
        n = self._n
        nn = n * n
        i = 1
        F = row[i : i + nn].reshape(n, n)
        i += nn
        x_pred = row[i : i + n]
        i += n
        P_pred = row[i : i + nn].reshape(n, n)
        i += nn
        x_filt = row[i : i + n]
        i += n
        P_filt = row[i : i + nn].reshape(n, n)
        return Step(float(row[0]), F, x_pred, P_pred, x_filt, P_filt)


@dataclass(frozen=True, slots=True)
class Corrections:
    """Sensor errors a mode estimates beside position and current."""

    heading_bias: float  # radians, added to the true heading
    speed_scale: float  # times the speed from the RPM map
    beacon_offset_n: float  # m, the error of the position the beacon reports
    beacon_offset_e: float
    # the weight of the belief that the config's calibration priors are wrong (the bank's)
    calibration_doubt: float | None = None
    # whether the config's priors are refuted, so the uncalibrated belief is followed
    calibration_refuted: bool | None = None


#: the ranges' common scale error as a checkpoint holds it (navd/filter/range_biases.py):
#: its estimate and variance
HeldScale = tuple[float, float]


@dataclass(frozen=True, slots=True)
class Held:
    """What a restart resumes beside the state vector and its covariance; None where the
    mode has no such thing or holds none now."""

    scale: HeldScale | None = None
    # the tracked beacon's outage under way: its report's time, its start, the offset
    # states' mean (n, e) and covariance (nn, ne, ee) then, the prediction's largest std
    # (navd/filter/ekf_ranges.py, RangeFusion.outage_held)
    outage: tuple[float, ...] | None = None
    # how often replies read long past the gate: the forgotten counts of such refusals and
    # of ranges (navd/filter/ekf_ranges.py, RangeFusion.long_refused)
    long_refused: tuple[float, float] | None = None
    # the range noise learnt beyond the config's: the forgotten sums of its pairs of
    # residuals (navd/filter/range_noise.py, RangeNoise.held)
    range_noise: tuple[float, ...] | None = None


class NavFilter(Protocol):
    """What the navigator needs of a filter mode.

    The modes differ in what they do with a range, and say so here rather than the
    navigator testing which mode it has.
    """

    @property
    def initialised(self) -> bool: ...

    @property
    def x(self) -> np.ndarray:
        """The state vector (its first two: latitude and longitude, radians)."""

    @property
    def P(self) -> np.ndarray: ...

    #: the range as the modem computed it, not re-derived with the water's sound speed
    ranges_as_reported: bool
    #: ranges are fused only while there is no fresh GPS fix (seed 000 Algorithm 2)
    ranges_only_without_gps: bool

    @property
    def last_nis(self) -> float:
        """Normalised innovation squared of the last range (NaN: the mode has no gate)."""

    @property
    def last_pull(self) -> float:
        """The share of the last range's residual its update moved the estimate by along
        the range's line of sight (NaN: the mode does not say)."""

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None: ...

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None: ...

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None: ...

    def checkpoint(self) -> tuple[np.ndarray, np.ndarray, Held]:
        """What a restart resumes from (navd/filter/navresume.py): the state, its
        covariance, and what else the mode holds that a restart needs."""

    def restore(
        self, x: np.ndarray, P: np.ndarray, grow_m2: float, held: Held | None = None
    ) -> None:
        """Navigate on from ``checkpoint``'s, the position variance grown by ``grow_m2``."""

    def range_update(self, m: RangeMeas) -> GateDecision: ...

    def estimate(self) -> StateEstimate: ...

    def apply_fix(self, fix: Fix) -> None:
        """An acoustic least-squares fix from the virtual net: a mode may take it."""

    def corrections(self) -> Corrections | None:
        """The sensor errors the mode estimates, if it estimates any."""


@runtime_checkable
class Smoothable(NavFilter, Protocol):
    """A mode the RTS smoother can run over: it records its steps when asked
    (``keep_history``), and says how its states differ and add up."""

    @property
    def history(self) -> History: ...

    def keep_history(self) -> None:
        """Record the steps from now on."""

    def close_history(self) -> None:
        """Let go of the recorded steps (their file)."""

    # a mode's state is its own vector: how two differ and a difference adds is the mode's
    def state_diff(self, a: np.ndarray, b: np.ndarray) -> np.ndarray: ...

    def state_apply(self, x: np.ndarray, dx: np.ndarray) -> np.ndarray: ...

    def estimate_of(self, x: np.ndarray, P: np.ndarray) -> StateEstimate: ...


def spread_about(a: StateEstimate, b: StateEstimate, w: float) -> StateEstimate:
    """``a`` with the covariance about its mean of the mixture that gives ``b`` the weight
    ``w``: ``(1 - w) P_a + w (P_b + d d^T)``, ``d`` ``b``'s mean seen from ``a``'s
    (kilometres apart at most); ``a`` itself where ``b`` is broken, which says nothing
    of ``a``'s spread."""
    n, e = geodesy.nearby_offset(a.lat, a.lon, b.lat, b.lon)
    if not all(map(math.isfinite, (n, e, b.var_n, b.var_e, b.cov_ne))):
        return a
    return StateEstimate(
        a.lat,
        a.lon,
        a.current_n,
        a.current_e,
        (1.0 - w) * a.var_n + w * (b.var_n + n * n),
        (1.0 - w) * a.var_e + w * (b.var_e + e * e),
        (1.0 - w) * a.cov_ne + w * (b.cov_ne + n * e),
    )


def principal_axes(nn: float, ee: float, ne: float) -> tuple[float, float, float]:
    """Eigenvalues (largest, smallest) of the symmetric 2 x 2 matrix [[nn, ne], [ne, ee]]
    in north-east axes, and the direction of the largest's axis in radians from north
    towards east: for a position covariance, the error ellipse's axes."""
    mean = 0.5 * (nn + ee)
    root = math.sqrt(0.25 * (nn - ee) ** 2 + ne * ne)
    return mean + root, mean - root, 0.5 * math.atan2(2.0 * ne, nn - ee)


def psd_part(nn: float, ee: float, ne: float) -> tuple[float, float, float]:
    """The positive semi-definite part of the symmetric 2x2 ``[[nn, ne], [ne, ee]]``: its
    negative eigenvalue, if any, taken as nothing; nothing where it is not finite."""
    if not math.isfinite(nn + ee + ne):
        return 0.0, 0.0, 0.0
    hi, lo, theta = principal_axes(nn, ee, ne)
    if lo >= 0.0:
        return nn, ee, ne
    if hi <= 0.0:
        return 0.0, 0.0, 0.0
    c, s = math.cos(theta), math.sin(theta)  # the axis of the positive eigenvalue
    return hi * c * c, hi * s * s, hi * c * s


def joseph_update(
    P: np.ndarray, H: np.ndarray, r_var: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Kalman gain and Joseph-form covariance update for one scalar measurement.

    Returns (K, P_new, S).  The Joseph form keeps P symmetric positive definite
    under round-off, which the plain (I - KH)P form does not guarantee.
    """
    PHt = P @ H
    S = float(H @ PHt) + r_var
    K = PHt / S
    IKH = np.eye(P.shape[0]) - np.outer(K, H)
    P_new = IKH @ P @ IKH.T + r_var * np.outer(K, K)
    return K, 0.5 * (P_new + P_new.T), S
