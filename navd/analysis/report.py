"""``navd report``: mission figures in the manner of seed 000 Figures 4.6-4.25, and a summary.

Inputs are the replay output (estimates and range decisions) and, optionally, the
measurement log (for the vehicle's GPS fixes) and the simulator's truth.  Tracks
are drawn on a local metric grid (east/north metres from the first estimate).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from navd import geodesy
from navd.analysis.score import TruthAt, score
from navd.analysis.surfacing import surfacing_error_gps
from navd.filter.advisory import replayed
from navd.formats import jsonlines
from navd.formats.mlog import LogError, read_measurement_log
from navd.formats.outputs import read_outputs
from navd.records import Gps
from navd.schema import split_outputs


def _read(path: str | Path) -> list[dict[str, Any]]:
    rows = []
    with open(path, "rb") as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                obj = jsonlines.loads(line)
            except jsonlines.DecodeError:
                raise LogError(f"{path}: line {n}: not JSON") from None
            if isinstance(obj, dict):
                rows.append(obj)
    return rows


_TRUTH_FIELDS = ("t", "lat", "lon", "depth", "current_n", "current_e", "boat_lat", "boat_lon")


def _read_truth(path: str | Path) -> list[dict[str, Any]]:
    """The simulator's truth (``truth.jsonl``); any other file is named as not one."""
    rows = _read(path)
    for n, row in enumerate(rows, 1):
        # an estimate has most of these too, but a type, which a truth sample has not
        if "type" in row or any(not isinstance(row.get(k), int | float) for k in _TRUTH_FIELDS):
            raise LogError(
                f"{path}: record {n} is not a truth sample (it needs "
                f"{', '.join(_TRUTH_FIELDS)}: the simulator's truth.jsonl)"
            )
    if not rows:
        raise LogError(f"{path}: no truth samples")
    return rows


RANGE_STD_M = 3.0  # the range noise the advisory weighs ranges with, when none is known


class _Grid:
    def __init__(self, lat0: float, lon0: float) -> None:
        self.lat0, self.lon0 = math.radians(lat0), math.radians(lon0)

    def en(self, lat: float, lon: float) -> tuple[float, float]:
        e, n, _ = geodesy.enu_offset(
            self.lat0, self.lon0, 0.0, math.radians(lat), math.radians(lon), 0.0
        )
        return e, n


def make_report(
    output: str | Path,
    out_dir: str | Path,
    truth: str | Path | None = None,
    measurements: str | Path | None = None,
) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    est, rng = split_outputs(read_outputs(output))
    if not est:
        raise LogError(f"{output}: no estimates to report (not a replay output or daemon log?)")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    grid = _Grid(est[0].lat, est[0].lon)
    fixes: list[Gps] = []
    if measurements:
        fixes = [r for r in read_measurement_log(measurements).records if isinstance(r, Gps)]
    tru = _read_truth(truth) if truth else []

    # -- track ---------------------------------------------------------------------
    fig, ax = plt.subplots(figsize=(8, 8))
    e, n = zip(*(grid.en(r.lat, r.lon) for r in est), strict=True)
    if tru:
        te, tn = zip(*(grid.en(s["lat"], s["lon"]) for s in tru[::10]), strict=True)
        ax.plot(te, tn, "k--", lw=1, label="truth")
    dr = [(r.dr_lat, r.dr_lon) for r in est if r.dr_lat is not None and r.dr_lon is not None]
    if dr:
        de, dn = zip(*(grid.en(lat, lon) for lat, lon in dr), strict=True)
        ax.plot(de, dn, color="magenta", lw=1, label="dead reckoning")
    ax.plot(e, n, color="green", lw=1.5, label="estimate")
    acc_t = {round(r.t, 1) for r in rng if r.accepted}
    acc = [grid.en(r.lat, r.lon) for r in est if round(r.t, 1) in acc_t]
    if acc:
        ax.plot(*zip(*acc, strict=True), "gx", ms=6, label="range accepted")
    if fixes:
        ge, gn = zip(
            *(grid.en(f.lat, f.lon) for f in fixes if f.lat is not None and f.lon is not None),
            strict=True,
        )
        ax.plot(ge, gn, "r.", ms=3, label="GPS fixes")
    bea = [
        grid.en(r.beacon_lat, r.beacon_lon)
        for r in rng
        if r.beacon_lat is not None and r.beacon_lon is not None
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
    fig.tight_layout()
    fig.savefig(out / "track.png", dpi=110)
    plt.close(fig)

    # -- ranges ----------------------------------------------------------------------
    # Time as minutes of the mission: a daemon's log counts its monotonic clock, which
    # means nothing to a reader; its estimates carry UTC, which names the start.
    t0 = est[0].t
    start = est[0].t_utc
    t_label = f"minutes since {start}" if start else f"minutes since t = {t0:.0f} s"

    def minutes(t: float) -> float:
        return (t - t0) / 60.0

    fig, ax = plt.subplots(figsize=(9, 4))
    a = [(minutes(r.t), r.range_m) for r in rng if r.accepted and r.range_m is not None]
    rj = [(minutes(r.t), r.range_m) for r in rng if not r.accepted and r.range_m is not None]
    # refused before a range was computed (no beacon position, say): counted, not plotted
    unplotted = sum(1 for r in rng if not r.accepted and r.range_m is None)
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
    fig.tight_layout()
    fig.savefig(out / "ranges.png", dpi=110)
    plt.close(fig)

    # -- current and uncertainty ---------------------------------------------------
    t = [minutes(r.t) for r in est]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax1.plot(t, [r.current_n for r in est], label="north")
    ax1.plot(t, [r.current_e for r in est], label="east")
    if tru:
        tt = [minutes(s["t"]) for s in tru]
        ax1.plot(tt, [s["current_n"] for s in tru], "C0--", lw=0.8)
        ax1.plot(tt, [s["current_e"] for s in tru], "C1--", lw=0.8)
    ax1.set_ylabel("current (m/s)")
    ax1.legend(fontsize=8)
    ax1.grid(True, alpha=0.3)
    ax2.plot(t, [r.std_n for r in est], label="1-sigma north")
    ax2.plot(t, [r.std_e for r in est], label="1-sigma east")
    if tru:
        truth_at = TruthAt(tru)
        err = []
        for r in est:
            s = truth_at(r.t)
            if s is not None:
                g = _Grid(s["lat"], s["lon"])
                err.append((minutes(r.t), math.hypot(*g.en(r.lat, r.lon))))
        if err:
            ax2.plot(*zip(*err, strict=True), "k", lw=0.8, label="error vs truth")
    ax2.set_xlabel(t_label)
    ax2.set_ylabel("metres")
    ax2.legend(fontsize=8)
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "current_uncertainty.png", dpi=110)
    plt.close(fig)

    # -- summary -------------------------------------------------------------------
    lines = [
        f"estimates: {len(est)} over {est[-1].t - est[0].t:.0f} s",
        f"ranges: {len(rng)} reached the filter, {sum(r.accepted for r in rng)} accepted, "
        f"{sum(not r.accepted for r in rng)} rejected",
    ]
    reasons: dict[str, int] = {}
    for d in rng:
        if not d.accepted:
            reasons[d.reason] = reasons.get(d.reason, 0) + 1
    if reasons:
        lines.append(
            "rejected by reason: " + ", ".join(f"{k} {v}" for k, v in sorted(reasons.items()))
        )
    surf = surfacing_error_gps(est, fixes)
    if surf is not None:
        lines.append(
            f"error at surfacing: {surf[0]:.1f} m against the first GPS fix, {surf[1]:.0f} s later"
        )
    sub = {round(e.t, 3) for e in est if e.mode == "submerged"}
    advice = [a for a in replayed(est, rng, RANGE_STD_M) if round(a.t, 3) in sub]
    if advice:
        weak = [a for a in advice if a.verdict == "weak_cross_range"]
        none = sum(1 for a in advice if a.verdict == "no_ranges")
        line = (
            f"observability while submerged: weak across the line of sight "
            f"{len(weak) / len(advice):.0%} of the time, no ranges {none / len(advice):.0%}"
        )
        if weak and weak[-1].suggest_heading_deg is not None:
            line += f" (last advice: steer {weak[-1].suggest_heading_deg:.0f} deg)"
        lines.append(line)
    sc = score([*est, *rng], tru) if tru else None
    if sc is not None and math.isfinite(sc.rms_m):
        lines.append(
            f"against the truth, submerged: RMS {sc.rms_m:.1f} m, at surfacing "
            f"{sc.surfacing_m:.1f} m, truth inside the 95 % ellipse {sc.inside95:.0%}"
        )
    elif sc is not None:
        lines.append(
            f"against the truth: no submerged estimate falls within {truth}'s time steps "
            "(the same mission, on the same time base?)"
        )
    last = est[-1]
    lines.append(
        f"final estimate: {last.lat:.7f}, {last.lon:.7f}; current "
        f"{last.current_n:+.3f} N {last.current_e:+.3f} E m/s"
    )
    lines.append(
        f"figures: {out / 'track.png'}, {out / 'ranges.png'}, {out / 'current_uncertainty.png'}"
    )
    text = "\n".join(lines)
    (out / "summary.txt").write_text(text + "\n", encoding="utf-8")
    return text
