"""A plain-numpy reference for ``make bench-replay``: what the hardware floor of a replay is.

``python -m bench.numpy_floor LOG OUT`` reads the same measurement log with orjson,
runs an 8-state EKF (position, current, heading bias, speed scale, beacon offset)
over the same 10 Hz steps, with a gated Joseph-form update for every range and GPS fix,
and writes one orjson line per step, as many as navd writes.  It has none of what
makes navd navd (the time rules, the gates, integrity, dead reckoning, the virtual
net, the geodesic step): it is the floor, not an alternative.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import orjson

_R = 6_378_137.0
_N = 8


def main(log: str, out: str, rate_hz: float = 10.0) -> int:
    dt = 1.0 / rate_hz
    x = np.zeros(_N)
    x[5] = 1.0
    # the compass is magnetic and uncorrected here: the heading-bias prior (0.3 rad) takes
    # the declination in, as the position and current priors take in the rest
    P = np.diag([225.0, 225.0, 0.04, 0.04, 0.09, 0.01, 4.0, 4.0])
    Q = np.diag([1e-3, 1e-3, 4e-6, 4e-6, 1e-8, 1e-8, 1e-4, 1e-4]) * dt
    eye = np.eye(_N)
    lat0 = lon0 = math.nan  # the first fix: the local plane's origin
    heading = speed = 0.0
    t_next = 0.0
    with open(log, "rb") as fh, open(out, "wb") as fo:
        fh.readline()
        for raw in fh:
            r = orjson.loads(raw)
            kind, t = r["type"], float(r["t"])
            while t >= t_next and not math.isnan(lat0):
                F = eye.copy()
                F[0, 2] = F[1, 3] = dt
                c, s = math.cos(heading + x[4]), math.sin(heading + x[4])
                u = speed * x[5]
                F[0, 4], F[1, 4] = -u * s * dt, u * c * dt
                F[0, 5], F[1, 5] = speed * c * dt, speed * s * dt
                x[0] += (u * c + x[2]) * dt
                x[1] += (u * s + x[3]) * dt
                P = F @ P @ F.T + Q
                xn, xe, cn, ce = x[:4].tolist()
                pn, pe, pne = float(P[0, 0]), float(P[1, 1]), float(P[0, 1])
                fo.write(orjson.dumps({
                    "type": "estimate", "t": t_next,
                    "lat": lat0 + math.degrees(xn / _R),
                    "lon": lon0 + math.degrees(xe / (_R * math.cos(math.radians(lat0)))),
                    "std_n": math.sqrt(pn), "std_e": math.sqrt(pe), "cov_ne": pne,
                    "current_n": cn, "current_e": ce,
                }, option=orjson.OPT_APPEND_NEWLINE))
                t_next += dt
            if kind == "heading":
                heading = math.radians(r["deg"])
            elif kind == "rpm":
                speed = r["rpm"] / 950.0
            elif kind == "gps" and r.get("lat") is not None:
                if math.isnan(lat0):
                    lat0, lon0, t_next = r["lat"], r["lon"], t
                    continue
                n = math.radians(r["lat"] - lat0) * _R
                e = math.radians(r["lon"] - lon0) * _R * math.cos(math.radians(lat0))
                H = np.zeros((2, _N))
                H[0, 0] = H[1, 1] = 1.0
                x, P = _update(x, P, H, np.array([n, e]) - x[:2], np.eye(2) * 16.0, eye)
            elif kind == "range" and not math.isnan(lat0) and r.get("beacon_lat") is not None:
                bn = math.radians(r["beacon_lat"] - lat0) * _R + x[6]
                be = math.radians(r["beacon_lon"] - lon0) * _R * math.cos(math.radians(lat0))
                be += x[7]
                dn, de = x[0] - bn, x[1] - be
                rho = max(math.hypot(dn, de), 1.0)
                H = np.zeros((1, _N))
                H[0, 0], H[0, 1], H[0, 6], H[0, 7] = dn / rho, de / rho, -dn / rho, -de / rho
                x, P = _update(x, P, H, np.array([r["m"] - rho]), np.array([[9.0]]), eye)
    return 0


def _update(
    x: np.ndarray, P: np.ndarray, H: np.ndarray, innov: np.ndarray, R: np.ndarray, eye: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    S = H @ P @ H.T + R
    if float(innov @ np.linalg.solve(S, innov)) > 9.0 * len(innov):
        return x, P  # a chi-square gate, as every range filter has (multipath)
    K = np.linalg.solve(S, H @ P).T
    IKH = eye - K @ H
    return x + K @ innov, IKH @ P @ IKH.T + K @ R @ K.T


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
