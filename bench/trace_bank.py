"""One Monte Carlo mission's calibration bank, tick by tick: where each belief puts the
vehicle against the truth, how sure it is, and what navd published.

For a mission whose figures want explaining (BENCHMARKS.md's traces of single seeds):
``python -m bench.trace_bank SEED --start T0 --end T1 --every S`` prints, every ``S``
seconds of filter time in ``[T0, T1]``, each belief's error north and east of the truth
(metres) with its own std, its heading bias (degrees) and speed scale with their std,
the uncalibrated belief's weight, whether the config's priors are refuted, and the
published std.  The mission is bench/robustness.py's draw of that seed, as drawn.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

import numpy as np

from bench.robustness import draw, fly
from navd.analysis.score import TruthAt, _ne_error
from navd.filter.bank import CalibrationBank
from navd.filter.common import StateEstimate


def _belief(x: np.ndarray, P: np.ndarray, e: StateEstimate, lat: float, lon: float) -> str:
    n, east = _ne_error(math.degrees(e.lat), math.degrees(e.lon), lat, lon)
    b, sb = math.degrees(float(x[4])), math.degrees(math.sqrt(float(P[4, 4])))
    s, ss = float(x[5]), math.sqrt(float(P[5, 5]))
    return (
        f"err ({n:7.1f},{east:7.1f}) std ({math.sqrt(e.var_n):6.1f},{math.sqrt(e.var_e):6.1f})"
        f" bias {b:5.1f}±{sb:4.1f} scale {s:.3f}±{ss:.3f}"
    )


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("seed", type=int)
    p.add_argument("--start", type=float, default=0.0, help="filter time to start at (s)")
    p.add_argument("--end", type=float, default=math.inf, help="filter time to end at (s)")
    p.add_argument("--every", type=float, default=10.0, help="seconds between lines")
    args = p.parse_args(argv)
    # per line: its time, each belief's state, covariance and estimate then, the weight,
    # the refutation and what was published
    Belief = tuple[np.ndarray, np.ndarray, StateEstimate]
    rows: list[tuple[float, Belief, Belief, float, bool, StateEstimate]] = []
    published = CalibrationBank.estimate

    def watched(bank: CalibrationBank) -> StateEstimate:
        est = published(bank)
        t = bank.config.t
        if args.start <= t <= args.end and (not rows or t >= rows[-1][0] + args.every):
            c, u = bank.config, bank.uncal
            rows.append((
                t, (c.x.copy(), c.P.copy(), c.estimate()), (u.x.copy(), u.P.copy(), u.estimate()),
                bank.w_uncal, bank.refuted, est,
            ))  # fmt: skip
        return est

    CalibrationBank.estimate = watched  # type: ignore[method-assign,assignment]
    try:
        _, err, truth = fly(draw(args.seed))
    finally:
        CalibrationBank.estimate = published  # type: ignore[method-assign,assignment]
    at = TruthAt(truth)
    for t, c, u, w, refuted, est in rows:
        s = at(t)
        if s is None:
            continue
        print(
            f"t {t:7.1f} depth {s.depth:5.1f} | config {_belief(*c, s.lat, s.lon)} | "
            f"uncal {_belief(*u, s.lat, s.lon)} | w {w:.2f} refuted {refuted} | "
            f"published std ({math.sqrt(est.var_n):6.1f},{math.sqrt(est.var_e):6.1f})"
        )
    if err:
        print(f"error: {err}")


if __name__ == "__main__":
    main()
