"""Types shared by the filter modes, and the step history the RTS smoother runs over."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from navd.filter.lsfix import Fix


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


@dataclass(frozen=True, slots=True)
class GateDecision:
    accepted: bool
    residual_m: float
    gate_m: float
    reason: str  # "ok", "gate", or why the range never reached the test


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
    x_pred: object
    P_pred: np.ndarray
    x_filt: object
    P_filt: np.ndarray


@dataclass(slots=True)
class History:
    steps: list[Step] = field(default_factory=list)
    enabled: bool = False

    def add(self, t: float, F: np.ndarray, x: object, P: np.ndarray) -> None:
        if self.enabled:
            self.steps.append(Step(t, F, x, P, x, P))

    def widen(self, P: np.ndarray) -> None:
        """Record covariance added outside a measurement (re-acquisition, a new prior).

        To the smoother it is process noise of the latest step, so it goes into the
        predicted covariance as well as the filtered one.
        """
        if self.enabled and self.steps:
            s = self.steps[-1]
            s.P_pred = s.P_pred + (P - s.P_filt)
            s.P_filt = P

    def correct(self, x: object, P: np.ndarray) -> None:
        """Replace the filtered state of the latest step after an update."""
        if self.enabled and self.steps:
            s = self.steps[-1]
            s.x_filt, s.P_filt = x, P


@dataclass(frozen=True, slots=True)
class Corrections:
    """Sensor errors a mode estimates beside position and current."""

    heading_bias: float  # radians, added to the true heading
    speed_scale: float  # times the speed from the RPM map
    beacon_offset_n: float  # m, the error of the position the beacon reports
    beacon_offset_e: float


class NavFilter(Protocol):
    """What the navigator needs of a filter mode.

    The modes differ in what they do with a range, and say so here rather than the
    navigator testing which mode it has.
    """

    initialised: bool
    history: History
    x: Any  # the state vector (its first two: latitude and longitude, radians)
    P: np.ndarray
    #: the range as the modem computed it, not re-derived with the water's sound speed
    ranges_as_reported: bool
    #: ranges are fused only while there is no fresh GPS fix (seed 000 Algorithm 2)
    ranges_only_without_gps: bool
    #: normalised innovation squared of the last range (NaN: the mode has no gate)
    last_nis: float

    def initialise(self, lat: float, lon: float, std_m: float, t: float) -> None: ...

    def predict(self, t: float, dt: float, heading: float, speed: float, hd: float) -> None: ...

    def gps_update(self, lat: float, lon: float, std_m: float, hd: float) -> None: ...

    def restore(self, x: np.ndarray, P: np.ndarray, grow_m2: float) -> None: ...

    def range_update(self, m: RangeMeas) -> GateDecision: ...

    def estimate(self) -> StateEstimate: ...

    def apply_fix(self, fix: Fix) -> None:
        """An acoustic least-squares fix from the virtual net: a mode may take it."""

    def corrections(self) -> Corrections | None:
        """The sensor errors the mode estimates, if it estimates any."""

    # a mode's state is its own (an array, or an array with a reference point)
    def state_diff(self, a: Any, b: Any) -> np.ndarray: ...

    def state_apply(self, x: Any, dx: np.ndarray) -> Any: ...

    def estimate_of(self, x: Any, P: np.ndarray) -> StateEstimate: ...


def principal_axes(nn: float, ee: float, ne: float) -> tuple[float, float, float]:
    """Eigenvalues (largest, smallest) of the symmetric 2 x 2 matrix [[nn, ne], [ne, ee]]
    in north-east axes, and the direction of the largest's axis in radians from north
    towards east: for a position covariance, the error ellipse's axes."""
    mean = 0.5 * (nn + ee)
    root = math.sqrt(0.25 * (nn - ee) ** 2 + ne * ne)
    return mean + root, mean - root, 0.5 * math.atan2(2.0 * ne, nn - ee)


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
