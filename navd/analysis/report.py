"""``navd report``: mission figures in the manner of seed 000 Figures 4.6-4.25, and a summary.

Inputs are the replay output (estimates and range decisions) and, optionally, the
measurement log (for the vehicle's GPS fixes) and the simulator's truth.  Tracks
are drawn on a local metric grid (east/north metres from the first estimate).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from navd import geodesy
from navd.analysis.score import TruthAt, score
from navd.analysis.surfacing import surfacing_error_gps
from navd.filter.advisory import replayed
from navd.formats.mlog import LogError, read_measurement_log
from navd.formats.outputs import read_outputs
from navd.formats.truth import TruthError, TruthSample, read_truth
from navd.records import Gps
from navd.schema import Estimate, RangeDecision, split_outputs

RANGE_STD_M = 3.0  # the range noise the advisory weighs ranges with, when none is known


class _Grid:
    def __init__(self, lat0: float, lon0: float) -> None:
        self.lat0, self.lon0 = math.radians(lat0), math.radians(lon0)

    def en(self, lat: float, lon: float) -> tuple[float, float]:
        e, n, _ = geodesy.enu_offset(
            self.lat0, self.lon0, 0.0, math.radians(lat), math.radians(lon), 0.0
        )
        return e, n


@dataclass(frozen=True, slots=True)
class ReportInput:
    """What a report is drawn from: the outputs, and optionally GPS fixes and the truth."""

    estimates: list[Estimate]
    decisions: list[RangeDecision]
    fixes: list[Gps]
    truth: list[TruthSample]
    truth_name: str = ""  # the truth file, for saying it does not match


def read_input(
    output: str | Path, truth: str | Path | None = None, measurements: str | Path | None = None
) -> ReportInput:
    est, rng = split_outputs(read_outputs(output))
    if not est:
        raise LogError(f"{output}: no estimates to report (not a replay output or daemon log?)")
    fixes: list[Gps] = []
    if measurements:
        fixes = [r for r in read_measurement_log(measurements).records if isinstance(r, Gps)]
    try:
        tru = read_truth(truth) if truth else []
    except TruthError as exc:
        raise LogError(str(exc)) from None
    return ReportInput(est, rng, fixes, tru, str(truth or ""))


def make_report(
    output: str | Path,
    out_dir: str | Path,
    truth: str | Path | None = None,
    measurements: str | Path | None = None,
) -> str:
    """The figures (track, ranges, current and uncertainty) and summary.txt; returns the
    summary."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = read_input(output, truth, measurements)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = [out / "track.png", out / "ranges.png", out / "current_uncertainty.png"]
    for draw, path in zip((_track, _ranges, _current), figures, strict=True):
        fig = draw(plt, r)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
    lines = summary(r)
    lines.append(f"figures: {', '.join(str(f) for f in figures)}")
    text = "\n".join(lines)
    (out / "summary.txt").write_text(text + "\n", encoding="utf-8")
    return text


def _track(plt: Any, r: ReportInput) -> Any:
    est, rng, fixes, tru = r.estimates, r.decisions, r.fixes, r.truth
    grid = _Grid(est[0].lat, est[0].lon)
    fig, ax = plt.subplots(figsize=(8, 8))
    e, n = zip(*(grid.en(x.lat, x.lon) for x in est), strict=True)
    if tru:
        te, tn = zip(*(grid.en(s.lat, s.lon) for s in tru[::10]), strict=True)
        ax.plot(te, tn, "k--", lw=1, label="truth")
    dr = [(x.dr_lat, x.dr_lon) for x in est if x.dr_lat is not None and x.dr_lon is not None]
    if dr:
        de, dn = zip(*(grid.en(lat, lon) for lat, lon in dr), strict=True)
        ax.plot(de, dn, color="magenta", lw=1, label="dead reckoning")
    ax.plot(e, n, color="green", lw=1.5, label="estimate")
    acc_t = {round(d.t, 1) for d in rng if d.accepted}
    acc = [grid.en(x.lat, x.lon) for x in est if round(x.t, 1) in acc_t]
    if acc:
        ax.plot(*zip(*acc, strict=True), "gx", ms=6, label="range accepted")
    gps = [grid.en(f.lat, f.lon) for f in fixes if f.lat is not None and f.lon is not None]
    if gps:
        ax.plot(*zip(*gps, strict=True), "r.", ms=3, label="GPS fixes")
    bea = [
        grid.en(d.beacon_lat, d.beacon_lon)
        for d in rng
        if d.beacon_lat is not None and d.beacon_lon is not None
    ]
    if bea:
        ax.plot(*zip(*bea, strict=True), "c^", ms=4, label="beacon (as reported)")
    ax.plot(e[0], n[0], "wD", mec="k", ms=8, label="start")
    ax.plot(e[-1], n[-1], "rD", mec="k", ms=8, label="end")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Track")
    return fig


def minutes_axis(est: list[Estimate]) -> tuple[Callable[[float], float], str]:
    """Time as minutes of the mission, and its label: a daemon's log counts its monotonic
    clock, which means nothing to a reader; its estimates carry UTC, which names the start."""
    t0 = est[0].t
    start = est[0].t_utc
    label = f"minutes since {start}" if start else f"minutes since t = {t0:.0f} s"
    return (lambda t: (t - t0) / 60.0), label


def _ranges(plt: Any, r: ReportInput) -> Any:
    minutes, t_label = minutes_axis(r.estimates)
    rng = r.decisions
    fig, ax = plt.subplots(figsize=(9, 4))
    a = [(minutes(d.t), d.range_m) for d in rng if d.accepted and d.range_m is not None]
    rj = [(minutes(d.t), d.range_m) for d in rng if not d.accepted and d.range_m is not None]
    # refused before a range was computed (no beacon position, say): counted, not plotted
    unplotted = sum(1 for d in rng if not d.accepted and d.range_m is None)
    if a:
        ax.plot(*zip(*a, strict=True), "bx", label=f"accepted ({len(a)})")
    if rj or unplotted:
        label = f"rejected ({len(rj) + unplotted}"
        label += f"; {unplotted} without a range, not drawn)" if unplotted else ")"
        ax.plot(*(zip(*rj, strict=True) if rj else ([], [])), "rx", label=label)
    ax.set_xlabel(t_label)
    ax.set_ylabel("range (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Ranges to the beacon")
    return fig


def errors_against_truth(r: ReportInput) -> list[tuple[float, float]]:
    """(t, horizontal error in metres) of every estimate within the truth's samples."""
    truth_at = TruthAt(r.truth)
    err = []
    for x in r.estimates:
        s = truth_at(x.t)
        if s is not None:
            err.append((x.t, math.hypot(*_Grid(s.lat, s.lon).en(x.lat, x.lon))))
    return err


def _current(plt: Any, r: ReportInput) -> Any:
    est, tru = r.estimates, r.truth
    minutes, t_label = minutes_axis(est)
    t = [minutes(x.t) for x in est]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax1.plot(t, [x.current_n for x in est], label="north")
    ax1.plot(t, [x.current_e for x in est], label="east")
    if tru:
        tt = [minutes(s.t) for s in tru]
        ax1.plot(tt, [s.current_n for s in tru], "C0--", lw=0.8)
        ax1.plot(tt, [s.current_e for s in tru], "C1--", lw=0.8)
    ax1.set_ylabel("current (m/s)")
    ax1.legend(fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(t, [x.std_n for x in est], label="1-sigma north")
    ax2.plot(t, [x.std_e for x in est], label="1-sigma east")
    err = errors_against_truth(r) if tru else []
    if err:
        ax2.plot([minutes(t) for t, _ in err], [e for _, e in err], "k", lw=0.8,
                 label="error vs truth")  # fmt: skip
    ax2.set_xlabel(t_label)
    ax2.set_ylabel("metres")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    return fig


def summary(r: ReportInput) -> list[str]:
    """The summary's lines (summary.txt, less the figures' names)."""
    est, rng = r.estimates, r.decisions
    lines = [
        f"estimates: {len(est)} over {est[-1].t - est[0].t:.0f} s",
        f"ranges: {len(rng)} reached the filter, {sum(d.accepted for d in rng)} accepted, "
        f"{sum(not d.accepted for d in rng)} rejected",
    ]
    reasons: dict[str, int] = {}
    for d in rng:
        if not d.accepted:
            reasons[d.reason] = reasons.get(d.reason, 0) + 1
    if reasons:
        lines.append(
            "rejected by reason: " + ", ".join(f"{k} {v}" for k, v in sorted(reasons.items()))
        )
    surf = surfacing_error_gps(est, r.fixes)
    if surf is not None:
        lines.append(
            f"error at surfacing: {surf[0]:.1f} m against the first GPS fix, {surf[1]:.0f} s later"
        )
    lines += _integrity(r)
    lines += _calibration(r)
    lines += _consistency(r)
    lines += _observability(r)
    lines += _against_truth(r)
    last = est[-1]
    lines.append(
        f"final estimate: {last.lat:.7f}, {last.lon:.7f}; current "
        f"{last.current_n:+.3f} N {last.current_e:+.3f} E m/s"
    )
    return lines


def _calibration(r: ReportInput) -> list[str]:
    """When the config's calibration priors were refuted, what the crew should change: the
    estimate followed the widened belief from then on (navd/filter/bank.py), and the next
    mission starts from the config again."""
    first = next((e for e in r.estimates if e.calibration_refuted), None)
    if first is None:
        return []
    last = r.estimates[-1]
    learned = ""
    if last.heading_bias_deg is not None and last.speed_scale is not None:
        learned = (
            f"; at the end: heading bias {last.heading_bias_deg:+.1f} deg, speed scale "
            f"{last.speed_scale:.3f}, current {last.current_n:+.2f} N {last.current_e:+.2f} E m/s"
        )
    return [
        f"calibration priors refuted at {first.t - r.estimates[0].t:.0f} s: the ranges put "
        "the current, heading bias or speed scale outside navigation.noise "
        "(current_init_std_mps, heading_bias_init_std_deg, speed_scale_init_std; measure or "
        f"widen them){learned}"
    ]


# accepted ranges the mean NIS needs before the report judges the noise model by it
_NIS_MIN_RANGES = 30
# A right noise model's accepted ranges average about 0.88: the gate cuts the tails at 3
# sigma short and 2 sigma long (the truncated normal's second moment; its std is 1.14).
# Past these the report says which way the model is off: half of 0.88 is two standard
# errors of the mean of the 30 ranges it needs and several of a mission's hundreds, yet
# near enough to act on.
_NIS_WIDE, _NIS_NARROW = 0.45, 2.0


@dataclass(frozen=True, slots=True)
class NoiseVerdict:
    """What the accepted ranges' residuals say of the noise model: the one test of the
    published ellipse a mission without truth allows (Bar-Shalom, Li and Kirubarajan 2001,
    5.4: the normalised innovation squared)."""

    mean_nis: float  # over every accepted range
    ranges: int
    # over the fixed beacons' ranges, which the verdict is taken from
    fixed_mean_nis: float
    fixed_ranges: int
    # wider (the ellipse likely wider than the error) | narrower | fits | unjudged (too few
    # ranges from fixed beacons)
    verdict: str


def _fixed(decisions: list[RangeDecision]) -> set[str]:
    """The beacons whose every reply put them at one place: surveyed transponders.  A
    moving beacon's ranges carry its reported position's error, mostly a boat's GPS
    wander, which outweighs the filter's own share of their variance and hides it."""
    where: dict[str, set[tuple[float, float] | None]] = {}
    for d in decisions:
        at = None
        if d.beacon_lat is not None and d.beacon_lon is not None:
            at = (round(d.beacon_lat, 7), round(d.beacon_lon, 7))
        where.setdefault(d.beacon, set()).add(at)
    return {b for b, places in where.items() if len(places) == 1 and None not in places}


def noise_verdict(decisions: Iterable[RangeDecision]) -> NoiseVerdict | None:
    """The verdict of the accepted ranges' mean NIS (None: too few ranges at all)."""
    usable = [
        (d, d.nis) for d in decisions if d.accepted and d.nis is not None and math.isfinite(d.nis)
    ]
    if len(usable) < _NIS_MIN_RANGES:
        return None
    mean = sum(v for _, v in usable) / len(usable)
    fixed = _fixed([d for d, _ in usable])
    nis = [v for d, v in usable if d.beacon in fixed]
    if len(nis) < _NIS_MIN_RANGES:
        return NoiseVerdict(mean, len(usable), math.nan, len(nis), "unjudged")
    fmean = sum(nis) / len(nis)
    verdict = "wider" if fmean < _NIS_WIDE else "narrower" if fmean > _NIS_NARROW else "fits"
    return NoiseVerdict(mean, len(usable), fmean, len(nis), verdict)


def _consistency(r: ReportInput) -> list[str]:
    v = noise_verdict(r.decisions)
    if v is None:
        return []
    line = f"ranges against the noise model: mean NIS {v.mean_nis:.2f} over {v.ranges} accepted"
    if v.verdict == "unjudged":
        return [
            line + "; no verdict on the ellipse: a moving beacon's ranges carry its reported "
            "position's error, which hides the filter's share (fixed transponders' ranges show it)"
        ]
    if v.fixed_ranges < v.ranges:
        line += f", {v.fixed_mean_nis:.2f} over the {v.fixed_ranges} from fixed transponders"
    line += " (about 0.9 when it fits)"
    if v.verdict == "wider":
        line += (
            ": the ranges agree with the estimate better than the model expects, so the "
            "published ellipse is likely wider than the error; if other missions here say "
            "the same, measure navigation.noise (range_std_m, current_walk_mps_per_sqrt_s) "
            "for this site"
        )
    elif v.verdict == "narrower":
        line += (
            ": the ranges disagree with the estimate more than the model allows, so the "
            "published ellipse is likely narrower than the error; check navigation.noise "
            "(range_std_m, the priors) and the sound speed"
        )
    return [line]


def _integrity(r: ReportInput, most: int = 3) -> list[str]:
    """How much of the submerged time an autopilot was told it could trust the estimate,
    and the commonest reasons it was not (their numbers taken out, so that "position std
    31 m over 25 m" and "... 40 m ..." count as one reason)."""
    sub = [e for e in r.estimates if e.mode == "submerged"]
    if not sub:
        return []
    states = {s: sum(1 for e in sub if e.integrity == s) for s in ("ok", "degraded", "lost")}
    line = "integrity while submerged: " + ", ".join(
        f"{s} {_share(n, len(sub))}" for s, n in states.items()
    )
    why: dict[str, int] = {}
    for e in sub:
        if e.integrity != "ok" and e.integrity_reason:
            kind = re.sub(r"\d+(\.\d+)?", "#", e.integrity_reason)
            why[kind] = why.get(kind, 0) + 1
    if why:
        top = sorted(why.items(), key=lambda kv: -kv[1])[:most]
        line += "; not ok for: " + ", ".join(f"{k} {_share(n, len(sub))}" for k, n in top)
    return [line]


def _share(n: int, of: int) -> str:
    """``n`` of ``of`` as a percentage, a little not rounded to nothing."""
    return "<1%" if 0 < n < 0.005 * of else f"{n / of:.0%}"


def _observability(r: ReportInput) -> list[str]:
    sub = {round(e.t, 3) for e in r.estimates if e.mode == "submerged"}
    advice = [a for a in replayed(r.estimates, r.decisions, RANGE_STD_M) if round(a.t, 3) in sub]
    if not advice:
        return []
    weak = [a for a in advice if a.verdict == "weak_cross_range"]
    none = sum(1 for a in advice if a.verdict == "no_ranges")
    line = (
        f"observability while submerged: weak across the line of sight "
        f"{len(weak) / len(advice):.0%} of the time, no ranges {none / len(advice):.0%}"
    )
    if weak and weak[-1].suggest_heading_deg is not None:
        line += f" (last advice: steer {weak[-1].suggest_heading_deg:.0f} deg)"
    return [line]


def _against_truth(r: ReportInput) -> list[str]:
    if not r.truth:
        return []
    sc = score([*r.estimates, *r.decisions], r.truth)
    if math.isfinite(sc.rms_m):
        return [
            f"against the truth, submerged: RMS {sc.rms_m:.1f} m, at surfacing "
            f"{sc.surfacing_m:.1f} m, truth inside the 95 % ellipse {sc.inside95:.0%}"
        ]
    return [
        f"against the truth: no submerged estimate falls within {r.truth_name}'s time steps "
        "(the same mission, on the same time base?)"
    ]
