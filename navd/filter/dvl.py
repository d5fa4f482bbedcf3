"""DVL dead reckoning with analytic error prediction (Diana & de Barros, seed 002).

* Body velocity from the DVL is rotated to north-east-down with the full attitude
  (eq. 10, roll-pitch-yaw) after the magnetic declination is added to the yaw
  (section 1.2), and integrated on the ellipsoid (eq. 2-4: the radii of curvature,
  here along the geodesic, navd/geodesy.py).
* Spike filter (section 1.3): a velocity that differs from the last accepted one by
  more than the vehicle could accelerate in the interval is replaced by the last
  accepted one, at most ``max_rejections`` times in a row, after which the DVL is
  believed again (the seed's guard against a filter that has itself diverged).
  The seed predicts with integrated IMU acceleration; navd has no accelerometer
  record, so the prediction is the last accepted velocity.
* Error prediction (eq. 14): the first-order velocity error from the sensors'
  specified errors ``dv_b`` (a fraction of each body velocity) and ``dTheta``
  (roll, pitch, yaw errors), accumulated in time as the seed's "relative error
  prediction".  From its rate, the time until it exceeds a limit: when to surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from navd.filter.deadreckoning import DeadReckoner


def rotation_body_to_ned(roll: float, pitch: float, yaw: float) -> list[list[float]]:
    """R_b^n of seed 002 eq. 10 (Z-Y-X Euler angles, radians)."""
    cf, sf = math.cos(roll), math.sin(roll)
    ct, st = math.cos(pitch), math.sin(pitch)
    cp, sp = math.cos(yaw), math.sin(yaw)
    return [
        [ct * cp, -sp * cf + cp * st * sf, sp * sf + cp * st * cf],
        [ct * sp, cp * cf + sp * st * sf, -cp * sf + sp * st * cf],
        [-st, ct * sf, ct * cf],
    ]


def velocity_error(
    v: tuple[float, float, float],
    att: tuple[float, float, float],
    dv: tuple[float, float, float],
    datt: tuple[float, float, float],
) -> tuple[float, float, float]:
    """First-order NED velocity error, seed 002 eq. 14 (all angles radians)."""
    vx, vy, vz = v
    f, t, p = att
    dvx, dvy, dvz = dv
    df, dt, dp = datt
    cf, sf = math.cos(f), math.sin(f)
    ct, st = math.cos(t), math.sin(t)
    cp, sp = math.cos(p), math.sin(p)
    dn = (
        ct * cp * dvx
        + (cp * st * sf - cf * sp) * dvy
        + (cf * cp * st + sf * sp) * dvz
        + ((cf * cp * st + sf * sp) * vy + (cf * sp - cp * st * sf) * vz) * df
        + (-cp * st * vx + ct * cp * sf * vy + ct * cf * cp * vz) * dt
        + (-ct * sp * vx + (-cf * cp - st * sf * sp) * vy + (cp * sf - cf * st * sp) * vz) * dp
    )
    de = (
        ct * sp * dvx
        + (st * sf * sp + cf * cp) * dvy
        + (cf * st * sp - cp * sf) * dvz
        + ((cf * st * sp - cp * sf) * vy + (-cf * cp - st * sf * sp) * vz) * df
        + (-st * sp * vx + ct * sf * sp * vy + ct * cf * sp * vz) * dt
        + (ct * cp * vx + (cp * st * sf - cf * sp) * vy + (sf * sp + cf * cp * st) * vz) * dp
    )
    dd = (
        -st * dvx
        + ct * sf * dvy
        + ct * cf * dvz
        + (ct * cf * vy - ct * sf * vz) * df
        + (-ct * vx - st * sf * vy - cf * st * vz) * dt
    )
    return dn, de, dd


@dataclass(frozen=True, slots=True)
class DvlSpec:
    velocity_error_frac: float = 0.05  # seed 002: 5 % of each body velocity
    attitude_error_deg: float = 3.0  # seed 002: 3 deg on roll, pitch and yaw
    max_accel_mps2: float = 0.5  # faster changes in velocity are spikes
    max_rejections: int = 5
    error_limit_m: float = 50.0  # surface before the predicted error exceeds this


class DvlDeadReckoner:
    def __init__(self, spec: DvlSpec, declination: float) -> None:
        self.spec = spec
        self.decl = declination
        self.track = DeadReckoner()
        self.t: float | None = None
        self.v: tuple[float, float, float] | None = None  # accepted body velocity
        self.att = (0.0, 0.0, 0.0)  # roll, pitch, true yaw (radians)
        self.rejections = 0
        self.spikes = 0
        self.distance_m = 0.0
        self.pred_error_m = 0.0
        self.error_rate_mps = 0.0

    @property
    def lat(self) -> float | None:
        return self.track.lat

    @property
    def lon(self) -> float | None:
        return self.track.lon

    def reset(self, lat: float, lon: float, t: float) -> None:
        self.track.reset(lat, lon)
        self.t = t
        self.distance_m = self.pred_error_m = 0.0

    def attitude(self, roll_deg: float, pitch_deg: float, yaw_mag_deg: float) -> None:
        self.att = (
            math.radians(roll_deg),
            math.radians(pitch_deg),
            math.radians(yaw_mag_deg) + self.decl,
        )

    def velocity(self, t: float, u: float, v: float, w: float) -> bool:
        """A DVL sample; False if it was taken for a spike and replaced."""
        ok = True
        if self.v is not None and self.t is not None:
            jump = math.dist((u, v, w), self.v)
            if jump > self.spec.max_accel_mps2 * max(t - self.t, 0.0) + 0.05:
                if self.rejections < self.spec.max_rejections:
                    self.rejections += 1
                    self.spikes += 1
                    ok = False
                else:
                    self.rejections = 0  # the filter diverged, not the DVL
        if ok:
            self.rejections = 0
        self._advance(t)
        if ok:
            self.v = (u, v, w)
        return ok

    def advance(self, t: float, hd: float = 0.0) -> None:
        self._advance(t, hd)

    def _advance(self, t: float, hd: float = 0.0) -> None:
        if self.t is None:
            self.t = t
            return
        dt = t - self.t
        self.t = t
        if dt <= 0 or self.v is None or self.lat is None or self.lon is None:
            return
        R = rotation_body_to_ned(*self.att)
        vn = sum(R[0][k] * self.v[k] for k in range(3))
        ve = sum(R[1][k] * self.v[k] for k in range(3))
        self.track.move(vn * dt, ve * dt, hd)
        self.distance_m += math.hypot(vn, ve) * dt
        s = self.spec
        dv = tuple(s.velocity_error_frac * abs(x) for x in self.v)
        da = (math.radians(s.attitude_error_deg),) * 3
        en, ee, _ = velocity_error(self.v, self.att, dv, da)  # type: ignore[arg-type]
        self.error_rate_mps = math.hypot(en, ee)
        self.pred_error_m += self.error_rate_mps * dt

    def time_to_limit_s(self) -> float | None:
        """Seconds until the predicted error passes the limit at the present rate."""
        left = self.spec.error_limit_m - self.pred_error_m
        if left <= 0:
            return 0.0
        if self.error_rate_mps <= 0:
            return None
        return left / self.error_rate_mps
