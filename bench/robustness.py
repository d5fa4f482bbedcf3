"""``make bench-robustness``: a Monte Carlo of missions over randomly drawn conditions.

One fixed draw of sensor errors can favour dead reckoning or flatter the filter
(BENCHMARKS.md, sensitivity), so every mission here draws its own: outlier rate
and length, drops in bursts, corrupted beacon positions, compass bias, RPM-map
error, the water's temperature as the crew measured it at the surface against the
column's mean (so its sound speed), current (often across the track and more than
half the vehicle's speed),
a boat anchored, drifting or motoring, a beacon 50 m to 2 km away, 10 to 60
minutes, and the single moving beacon or 2- and 3-transponder LBL.  Each mission is
first drawn into a class (``CLASSES``): the base draw above, or priors 3 to 10 times
too small, short straight runs near the beacon, 2 to 3 hour surveys with surfacings,
a tidal stream that turns, the boat's location line down for minutes.  Seeds are a
fixed list, so the table is reproducible; none of the bundled scenarios is used.
Each mission is also compared with its posterior Cramer-Rao bound (navd/hil/bound.py).

Each mission goes through the ``navd replay`` command line in the default and
thesis modes (dead reckoning comes with the default output) and is scored against
the simulator's truth.  A divergence is a final error above max(100 m, 2 x the
thesis mode's final error) or an RMS current error above 0.5 m/s.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import random
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from bench.common import replay_mission, report
from navd.analysis.jobs import default_jobs, run_all
from navd.analysis.score import (
    CHI2_2DOF_99,
    REACQUIRED_S,
    AgainstBound,
    Score,
    against_bound,
    score,
)
from navd.formats.truth import TruthSample, read_truth
from navd.hil.bound import MATCHED_PARTS, matched_config, mission_bound
from navd.hil.scenario import scenario_from_dict
from navd.hil.sim_cli import mission_config, write_mission
from navd.hil.world import Mission, simulate
from navd.schema import Output
from navd.settings import Config, NoiseConfig, config_from_dict
from navd.utc import utc_seconds

DIVERGED_FINAL_M = 100.0
DIVERGED_CURRENT_MPS = 0.5
# the K-th other draw of a mission's noise (``--noise-draw``) is seeded K strides above
# the mission's seed: above every mission seed, so no two runs share a noise stream
NOISE_DRAW_STRIDE = 100_000


#: the classes a mission is drawn in, and their weights in the draw
CLASSES: dict[str, int] = {
    "base": 4,  # everything drawn wide: the moving beacon, or 2 or 3 transponders
    "wrong-prior": 2,  # the config's priors 3 to 10 times too small
    "short-near": 1,  # short straight runs within 300 m of the beacon
    "long-survey": 1,  # 2 to 3 hours, surfacing for GPS, a tidal stream
    "tidal-turning": 1,  # a tidal stream that turns during the mission
    "boat-outage": 1,  # the boat's location line down for 1 to 5 minutes
}
#: the geometries a base mission is drawn in (weights 3, 1, 1): a moving beacon, or a
#: net of 2 or 3 surveyed transponders
KINDS = ["beacon", "lbl-2", "lbl-3"]
# what the draws of the base class spread the sensor errors over, as one-sigma per axis
# (the Cramer-Rao bound's priors for the missions that draw them)
_CURRENT_MAX_MPS = 1.0
_BIAS_MAX_DEG = 6.0
_RPM_ERR_MAX = 0.12
# how far the crew's surface temperature is from the water column's mean (C, uniform)
_TEMPERATURE_ERR_MAX_C = 3.0


@dataclass(frozen=True, slots=True)
class Draw:
    seed: int
    kind: str  # beacon, lbl-2, lbl-3
    outliers: float
    drops: float
    cross_current: bool  # across the track and faster than half the vehicle's speed
    scenario: dict[str, Any]
    cls: str = "base"


def _legs(
    rng: random.Random,
    pattern: str,
    heading: float,
    duration: float,
    lo: float = 60.0,
    hi: float = 400.0,
) -> list[dict[str, Any]]:
    legs, t, k = [], 0.0, 0
    while t < duration:
        d = min(duration - t, rng.uniform(lo, hi))
        if pattern == "straight":
            h = heading + rng.uniform(-10.0, 10.0)
        elif pattern == "lawnmower":
            h = heading + (180.0 if k % 2 else 0.0)
        else:
            h = rng.uniform(0.0, 360.0)
        legs.append({"heading_deg": round(h % 360.0, 1), "duration_s": round(d, 1)})
        t += d
        k += 1
    return legs


def draw(seed: int) -> Draw:
    """The conditions of mission ``seed``: its class, then every error drawn, none chosen."""
    rng = random.Random(seed)
    cls = rng.choices(list(CLASSES), weights=list(CLASSES.values()))[0]
    kind = rng.choices(KINDS, weights=[3, 1, 1])[0]
    if cls != "base":
        kind = "beacon"
    speed = rng.uniform(1.0, 2.0)
    duration = rng.uniform(600.0, 3600.0)
    heading = rng.uniform(0.0, 360.0)
    pattern = rng.choice(["straight", "lawnmower", "random"])
    if cls == "short-near":
        duration = rng.uniform(300.0, 900.0)
        pattern = "straight"
    elif cls == "long-survey":
        duration = rng.uniform(7200.0, 10800.0)
        pattern = "lawnmower"
    elif cls == "tidal-turning":
        duration = rng.uniform(3600.0, 7200.0)
    legs = _legs(rng, pattern, heading, duration)
    if cls == "long-survey":
        # up for GPS every 30 to 45 minutes, for 1 to 3 minutes
        every = rng.uniform(1800.0, 2700.0)
        out, t, next_up = [], 0.0, every
        for leg in legs:
            out.append(leg)
            t += leg["duration_s"]
            if t >= next_up and t < duration - 600.0:
                out.append(
                    {**leg, "duration_s": round(rng.uniform(60.0, 180.0), 1), "depth_m": 0.0}
                )
                next_up = t + every
        legs = out
    cur_speed = rng.uniform(0.0, _CURRENT_MAX_MPS)
    cur_dir = rng.uniform(0.0, 360.0)
    across = abs(math.sin(math.radians(cur_dir - heading)))
    outliers = rng.uniform(0.0, 0.5)
    drops = rng.uniform(0.0, 0.5)
    corrupt = rng.uniform(0.0, 0.1)
    rpm_true = rng.uniform(850.0, 1000.0)
    rpm_err = rng.uniform(-_RPM_ERR_MAX, _RPM_ERR_MAX)
    bias = rng.uniform(-_BIAS_MAX_DEG, _BIAS_MAX_DEG)
    current: dict[str, Any] = {"speed_mps": round(cur_speed, 3), "toward_deg": round(cur_dir, 1)}
    navigation: dict[str, Any] = {}
    if cls == "wrong-prior":
        # errors of a real size, priors that claim 3 to 10 times less
        cur_speed = rng.uniform(0.3, 0.8)
        bias = rng.choice([-1, 1]) * rng.uniform(3.0, 8.0)
        rpm_err = rng.choice([-1, 1]) * rng.uniform(0.05, 0.15)
        current["speed_mps"] = round(cur_speed, 3)
        navigation["noise"] = _too_small(cur_speed, bias, rpm_err, rng)
    elif cls in ("long-survey", "tidal-turning"):
        amp = rng.uniform(0.2, 0.8)
        period = rng.uniform(40000.0, 46000.0)  # semidiurnal
        current["speed_mps"] = round(rng.uniform(0.0, 0.3) if cls == "long-survey" else 0.0, 3)
        current["tidal_amplitude_mps"] = round(amp, 3)
        current["tidal_period_s"] = round(period, 0)
        if cls == "tidal-turning":
            # slack water (the turn) somewhere in the middle half of the mission
            t_slack = rng.uniform(0.25, 0.75) * duration
            phase = -360.0 * t_slack / period + rng.choice([0.0, 180.0])
            current["tidal_phase_deg"] = round((phase + 180.0) % 360.0 - 180.0, 2)
        else:
            current["tidal_phase_deg"] = round(rng.uniform(-180.0, 180.0), 1)
        cur_speed = current["speed_mps"] + amp
    navigation["speed"] = {"rpm_per_mps": round(rpm_true * (1 + rpm_err), 1)}
    sc: dict[str, Any] = {
        "name": f"mc-{seed}",
        "description": f"Monte Carlo draw, class {cls} (bench/robustness.py)",
        "bench": False,
        "vehicle": {
            "lat": round(rng.uniform(-60.0, 60.0), 4),
            "lon": round(rng.uniform(-179.0, 179.0), 4),
            "speed_mps": round(speed, 2),
            "depth_m": round(rng.uniform(2.0, 20.0), 1),
            "legs": legs,
        },
        "current": current,
        "sensors": {
            "declination_deg": round(rng.uniform(-20.0, 20.0), 1),
            "compass_bias_deg": round(bias, 2),
            "rpm_per_mps": round(rpm_true, 1),
        },
        "acoustics": {
            "ping_interval_s": 10.0 if kind == "beacon" else 4.0,
            "multipath_prob": round(outliers, 3),
            "multipath_min_m": 3.0,
            "multipath_max_m": 300.0,
            "drop_prob": round(drops, 3),
            "drop_burst_pings": round(rng.uniform(1.0, 4.0), 2),
            "corrupt_position_prob": round(corrupt / 2, 4),
            "corrupt_gross_prob": round(corrupt / 2, 4),
            "temperature_c": round(rng.uniform(4.0, 25.0), 1),
            "salinity_ppt": round(rng.choice([0.2, 33.0, 35.0]), 1),
        },
        "config": {"navigation": navigation},
    }
    # from its own generator, so that every other draw of a seed stays what it was
    t_err = random.Random(f"sound-{seed}").uniform(-1.0, 1.0) * _TEMPERATURE_ERR_MAX_C
    t_crew = sc["acoustics"]["temperature_c"] + t_err
    navigation["sound_speed"] = {"temperature_c": round(t_crew, 1)}
    dist = rng.uniform(50.0, 2000.0)
    if cls == "short-near":
        dist = rng.uniform(20.0, 300.0)
    bearing = math.radians(rng.uniform(0.0, 360.0))
    if kind == "beacon":
        motion = rng.choice(["anchored", "drifting", "motoring"])
        if cls == "short-near":
            motion = rng.choice(["anchored", "drifting"])
        elif cls == "boat-outage":
            motion = rng.choice(["drifting", "motoring"])
        sc["boat"] = {
            "north_m": round(dist * math.cos(bearing), 1),
            "east_m": round(dist * math.sin(bearing), 1),
            "speed_mps": round(rng.uniform(0.2, 1.0), 2) if motion == "motoring" else 0.0,
            "heading_deg": round(rng.uniform(0.0, 360.0), 1),
            "drifts_with_current": motion == "drifting",
        }
        if cls == "boat-outage":
            # a boat motoring on a line holds its course within a few degrees
            sc["boat"]["course_wander_deg_per_sqrt_s"] = round(rng.uniform(1.0, 5.0), 2)
            sc["acoustics"]["location_outages"] = rng.randint(1, 3)
            sc["acoustics"]["location_outage_min_s"] = 60.0
            sc["acoustics"]["location_outage_max_s"] = 300.0
    else:
        n = 2 if kind == "lbl-2" else 3
        along = n == 2 and rng.random() < 0.5  # the track runs along the baseline
        tps = []
        for i in range(n):
            b = math.radians(heading) if along else bearing + 2 * math.pi * i / n
            r = dist * (1 if i % 2 == 0 else -1) if along else dist * rng.uniform(0.5, 1.0)
            tps.append(
                {
                    "name": f"t{i + 1}",
                    "north_m": round(r * math.cos(b), 1),
                    "east_m": round(r * math.sin(b), 1),
                    "depth_m": round(rng.uniform(5.0, 30.0), 1),
                }
            )
        sc["acoustics"]["transponders"] = tps
    return Draw(seed, kind, outliers, drops, cur_speed > 0.5 * speed and across > 0.7, sc, cls)


@dataclass(frozen=True, slots=True)
class Result:
    draw: Draw
    default: Score | None
    thesis: Score | None
    error: str = ""  # a replay that failed (an exception in the navigator)
    bound_m: float = math.nan  # the mission's Cramer-Rao bound (navd/hil/bound.py), RMS
    against: AgainstBound | None = None  # the default's ellipses beside the bound's

    @property
    def diverged(self) -> bool:
        d, t = self.default, self.thesis
        if d is None or t is None:
            return True
        limit = max(DIVERGED_FINAL_M, 2.0 * t.surfacing_m)
        return d.surfacing_m > limit or d.current_rms_mps > DIVERGED_CURRENT_MPS


def _too_small(
    current_mps: float, bias_deg: float, scale_err: float, rng: random.Random
) -> dict[str, float]:
    """Config priors on the current, heading bias and speed scale 3 to 10 times smaller
    than these errors (per axis for the current), each with a floor, so that a mission
    with almost none of an error is still told less."""
    k = [rng.uniform(3.0, 10.0) for _ in range(3)]
    return {
        "current_init_std_mps": round(max(current_mps, 0.05) / math.sqrt(2.0) / k[0], 4),
        "heading_bias_init_std_deg": round(max(abs(bias_deg), 0.5) / k[1], 3),
        "speed_scale_init_std": round(max(abs(scale_err), 0.01) / k[2], 4),
    }


def wrong_priors(dr: Draw) -> Draw:
    """The same mission with the config's priors on the current, heading bias and speed
    scale 3 to 10 times smaller than the mission's own errors, as the wrong-prior class
    draws them, whatever its class (from a generator of its own, so that every other draw
    stays as it was): the wrong-prior class is long and wide, and this asks whether the
    other classes' geometry (a short run near the beacon, a net) stays honest too."""
    if dr.cls == "wrong-prior":
        return dr
    sc = dr.scenario
    current, sensors = sc["current"], sc["sensors"]
    noise = _too_small(
        current["speed_mps"] + current.get("tidal_amplitude_mps", 0.0),
        sensors["compass_bias_deg"],
        sc["config"]["navigation"]["speed"]["rpm_per_mps"] / sensors["rpm_per_mps"] - 1.0,
        random.Random(f"wrong-priors-{dr.seed}"),
    )
    navigation = {**sc["config"]["navigation"], "noise": noise}
    return replace(dr, scenario={**sc, "config": {**sc["config"], "navigation": navigation}})


def wide_ranges(dr: Draw) -> Draw:
    """The same mission with its ranges noisier than the config says: the range noise the
    config's ``range_std_m`` (its default, as the Monte Carlo's crews keep it) times 1.5
    to 3 (from a generator of its own, so that every other draw stays as it was).  The
    range noise is a prior too, one a crew takes from another site's trials (Fulton's 3 m
    at 12 kHz over kilometres, seed 003), and the filter must not grow sure of a place
    its ranges do not give."""
    k = random.Random(f"wide-ranges-{dr.seed}").uniform(1.5, 3.0)
    acoustics = {
        **dr.scenario["acoustics"],
        "range_noise_m": round(k * NoiseConfig().range_std_m, 2),
    }
    return replace(dr, scenario={**dr.scenario, "acoustics": acoustics})


# How far the bench takes a crew's tidal prediction to be off (an assumption, not a
# measurement: a station's prediction some kilometres from the mission, the speed of
# maximum flood to a fifth, its time to half an hour, the flood's direction to 10 degrees).
TIDE_SPEED_ERR = 0.2
TIDE_TIME_ERR_S = 1800.0
TIDE_DIRECTION_ERR_DEG = 10.0


def tide_prediction(dr: Draw) -> Draw:
    """The same mission with its crew given a prediction of its tidal stream
    (``navigation.tide``), off in speed, time and direction by up to ``TIDE_*_ERR`` (from a
    generator of its own, so that every other draw stays as it was); a mission whose water
    has no tide as drawn."""
    c = dr.scenario["current"]
    amp = float(c.get("tidal_amplitude_mps", 0.0))
    if amp <= 0.0:
        return dr
    rng = random.Random(f"tide-prediction-{dr.seed}")
    sc = scenario_from_dict(dr.scenario)
    period = sc.current.tidal_period_s
    # the simulator's stream is amp sin(2 pi t / T + phase) along toward_deg
    # (navd/hil/world.py): the flood is greatest where the sine is 1
    t_flood = (0.5 * math.pi - math.radians(sc.current.tidal_phase_deg)) * period / (2 * math.pi)
    start = utc_seconds(sc.start_utc)
    if start is None:
        raise ValueError(f"mission {dr.seed}: start_utc {sc.start_utc!r} is not a UTC time")
    flood = start + t_flood + rng.uniform(-TIDE_TIME_ERR_S, TIDE_TIME_ERR_S)
    tide = {
        "amplitude_mps": round(amp * (1.0 + rng.uniform(-TIDE_SPEED_ERR, TIDE_SPEED_ERR)), 3),
        "toward_deg": round(
            (sc.current.toward_deg + rng.uniform(-TIDE_DIRECTION_ERR_DEG, TIDE_DIRECTION_ERR_DEG))
            % 360.0,
            1,
        ),
        "max_flood_utc": dt.datetime.fromtimestamp(round(flood), dt.UTC).isoformat(),
        "period_s": period,
    }
    navigation = {**dr.scenario["config"]["navigation"], "tide": tide}
    return replace(
        dr, scenario={**dr.scenario, "config": {**dr.scenario["config"], "navigation": navigation}}
    )


def noise_seed(seed: int, k: int) -> int | None:
    """The seed of mission ``seed``'s ``k``-th other draw of noise (None: as drawn)."""
    if k <= 0:
        return None
    if not 0 < seed < NOISE_DRAW_STRIDE:
        raise ValueError(f"mission seeds run from 1 to {NOISE_DRAW_STRIDE - 1}")
    return k * NOISE_DRAW_STRIDE + seed


def clean(dr: Draw) -> Draw:
    """The same mission with no outliers to refuse: no multipath and no corrupt beacon
    positions, the ranges an ideal outlier detector would keep (drops stay: a ping that
    never came is no outlier, and the bound counts without it too)."""
    acoustics = {
        **dr.scenario["acoustics"],
        "multipath_prob": 0.0,
        "corrupt_position_prob": 0.0,
        "corrupt_gross_prob": 0.0,
    }
    return replace(dr, outliers=0.0, scenario={**dr.scenario, "acoustics": acoustics})


def fly(dr: Draw) -> tuple[list[Output], str, list[TruthSample]]:
    """Mission ``dr`` simulated with its own seed's noise and replayed by the default mode,
    in a directory of its own that is gone after: its outputs, the error the replay ended
    with ("" when none), and its truth."""
    with tempfile.TemporaryDirectory(prefix="navd-fly-") as td:
        d = Path(td) / "m"
        write_flown(dr, d, None, None)
        truth = read_truth(d / "truth.jsonl")
        out, err = replay_mission(d, "default")
    return out, err, truth


def variant(seed: int, no_outliers: bool, wrong: bool, wide: bool, tide: bool = False) -> Draw:
    """Mission ``seed``'s conditions as drawn, or without its outliers (:func:`clean`),
    with its priors too small (:func:`wrong_priors`), with its ranges noisier than the
    config says (:func:`wide_ranges`), with its crew's tidal prediction
    (:func:`tide_prediction`)."""
    dr = clean(draw(seed)) if no_outliers else draw(seed)
    if wrong:
        dr = wrong_priors(dr)
    if wide:
        dr = wide_ranges(dr)
    if tide:
        dr = tide_prediction(dr)
    return dr


def write_flown(
    dr: Draw, d: Path, noise_seed: int | None, matched: tuple[str, ...] | None
) -> tuple[Mission, Config]:
    """Mission ``dr`` simulated (with ``noise_seed``'s draw of noise, or its own seed's)
    and written to ``d`` with its crew's config, given those parts of the bound's own
    model when ``matched`` (navd/hil/bound.py, ``matched_config``): the mission and the
    crew's config."""
    mission = simulate(scenario_from_dict(dr.scenario), noise_seed or dr.seed)
    crew = config_from_dict(mission_config(mission))
    write_mission(mission, d, None if matched is None else matched_config(mission, crew, matched))
    return mission, crew


def selected(missions: int, only: str | None, kind: str | None, first: int = 1) -> list[int]:
    """Of seeds ``first``..``missions``, those of class ``only`` and geometry ``kind`` (if
    given)."""
    seeds = list(range(first, missions + 1))
    if only:
        seeds = [s for s in seeds if draw(s).cls == only]
    if kind:
        seeds = [s for s in seeds if draw(s).kind == kind]
    return seeds


def run_one(
    seed: int,
    workdir: str,
    noise_seed: int | None = None,
    no_outliers: bool = False,
    matched: tuple[str, ...] | None = None,
    wrong: bool = False,
    wide: bool = False,
    tide: bool = False,
) -> Result:
    """Mission ``seed``; with ``noise_seed``, its conditions with another draw of noise;
    with ``no_outliers``, without its outliers (:func:`clean`); with ``matched``, navd
    given those parts of the bound's own model of the mission (navd/hil/bound.py,
    ``matched_config``); with ``wrong``, its priors too small (:func:`wrong_priors`); with
    ``wide``, its ranges noisier than the config says (:func:`wide_ranges`); with ``tide``,
    its crew's tidal prediction (:func:`tide_prediction`)."""
    dr = variant(seed, no_outliers, wrong, wide, tide)
    d = Path(workdir) / f"mc-{seed}-{noise_seed}"
    mission, crew = write_flown(dr, d, noise_seed, matched)
    b = mission_bound(mission, crew)
    truth = read_truth(d / "truth.jsonl")
    out_d, err_d = replay_mission(d, "default")
    out_t, err_t = replay_mission(d, "thesis")
    result = Result(
        dr,
        score(out_d, truth) if out_d else None,
        score(out_t, truth) if out_t else None,
        err_d or err_t,
        b.rms_m,
        against_bound(out_d, truth, b.ellipses) if out_d else None,
    )
    shutil.rmtree(d, ignore_errors=True)
    return result


def _mean(xs: list[float]) -> float:
    xs = [x for x in xs if not math.isnan(x)]
    return statistics.fmean(xs) if xs else math.nan


def _rms(xs: list[float]) -> float:
    xs = [x for x in xs if not math.isnan(x)]
    return math.sqrt(statistics.fmean([x * x for x in xs])) if xs else math.nan


def _reacquired(results: list[Result]) -> str:
    """How the ellipse holds the truth in the quarter of an hour after a re-acquisition,
    against the whole submerged time, over the missions that re-acquired (means over
    missions, as the table's in95)."""
    after = [r.default for r in results if r.default and r.default.reacquired_estimates]
    if not after:
        return "No mission re-acquired."
    return (
        f"In the {REACQUIRED_S / 60:.0f} minutes after each of the default's "
        f"re-acquisitions ({len(after)} missions), the truth lies inside the 95 % ellipse "
        f"{_mean([x.reacquired_inside95 for x in after]):.3f} of the time; over the same "
        f"missions' whole submerged time {_mean([x.inside95 for x in after]):.3f}."
    )


def _row(name: str, rs: list[Result]) -> str:
    ok = [r for r in rs if r.default is not None and r.thesis is not None]
    d = [r.default for r in ok if r.default is not None]
    t = [r.thesis for r in ok if r.thesis is not None]
    rms_d = _mean([x.rms_m for x in d])
    rms_t = _mean([x.rms_m for x in t])
    rms_dr = _mean([x.dr_rms_m for x in d])
    beats_dr = sum(1 for x in d if x.rms_m <= x.dr_rms_m) / len(d) if d else math.nan
    # against the bound: the root mean square over missions of each side
    bounded = [r for r in ok if not math.isnan(r.bound_m) and r.default is not None]
    ratio = (
        _rms([r.default.rms_m for r in bounded if r.default]) / _rms([r.bound_m for r in bounded])
        if bounded
        else math.nan
    )
    beside = [r.against for r in ok if r.against is not None]
    ellipse = (
        _rms([a.published_std_m for a in beside]) / _rms([a.bound_std_m for a in beside])
        if beside
        else math.nan
    )
    return (
        f"| {name} | {len(rs)} | {sum(1 for r in rs if r.error)} | "
        f"{sum(1 for r in rs if r.diverged)} | {rms_d:.1f} | "
        f"{_mean([r.bound_m for r in bounded]):.1f} | {ratio:.2f} | {rms_t:.1f} | {rms_dr:.1f} | "
        f"{rms_d / rms_t:.2f} | {beats_dr:.2f} | "
        f"{_mean([x.inside95 for x in d]):.2f} | "
        f"{_mean([a.inside95 for a in beside]):.2f} | {ellipse:.2f} | "
        f"{_mean([x.ok_inside99 for x in d]):.3f} | "
        f"{_mean([x.ok_fraction for x in d]):.2f} | "
        f"{_mean([x.current_rms_mps for x in d]):.3f} |"
    )


def table(results: list[Result], n: int, first: int = 1) -> str:
    classes: list[tuple[str, list[Result]]] = [
        (f"class {c}", [r for r in results if r.draw.cls == c]) for c in CLASSES
    ]
    classes += [
        ("single moving beacon", [r for r in results if r.draw.kind == "beacon"]),
        ("2-transponder LBL", [r for r in results if r.draw.kind == "lbl-2"]),
        ("3-transponder LBL", [r for r in results if r.draw.kind == "lbl-3"]),
        ("outliers < 15 %", [r for r in results if r.draw.outliers < 0.15]),
        ("outliers 15-35 %", [r for r in results if 0.15 <= r.draw.outliers < 0.35]),
        ("outliers >= 35 %", [r for r in results if r.draw.outliers >= 0.35]),
        ("drops >= 35 %", [r for r in results if r.draw.drops >= 0.35]),
        ("cross-current > half the speed", [r for r in results if r.draw.cross_current]),
        ("**all**", results),
    ]
    lines = [
        f"{n - first + 1} missions, seeds {first}..{n}, each with its own drawn class and "
        "conditions",
        "(bench/robustness.py). RMS over the submerged part, in metres; *bound* = the",
        "mission's posterior Cramer-Rao bound (navd/hil/bound.py), mean over the class;",
        "*/ bound* = the class's RMS over missions of the default's RMS, over that of",
        "the bound; *in95* = fraction of submerged time the truth lies inside the 95 %",
        "ellipse; *ok in99* = while integrity said ok, the fraction of that time the",
        "truth lies inside the 99 % ellipse; *ok* = fraction of submerged time integrity",
        "said ok; *cur* = RMS current error (m/s); *default <= DR* = fraction of missions",
        "where the default mode's RMS is no worse than dead reckoning's; *in95 at bound* =",
        "the same fraction for a 95 % ellipse of the bound's own covariance drawn about",
        "the estimate (what these estimates would score were they as sure as the bound",
        "allows: the yardstick for *in95*); *ellipse / bound* = the class's RMS published",
        "std over the bound's.",
        "",
        "| class | missions | exceptions | divergences | default rms | bound | / bound "
        "| thesis rms | DR rms | default / thesis | default <= DR | in95 | in95 at bound "
        "| ellipse / bound | ok in99 | ok | cur |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [_row(name, rs) for name, rs in classes if rs]
    lines += ["", _reacquired(results)]
    bad = [r for r in results if r.error or r.diverged]
    if bad:
        lines += ["", "Missions that raised or diverged:", ""]
        for r in bad[:20]:
            d = r.default
            what = r.error or (
                f"final {d.surfacing_m:.0f} m ({_known(d)}), current error "
                f"{d.current_rms_mps:.2f} m/s"
                if d
                else "no output"
            )
            lines.append(
                f"- seed {r.draw.seed} ({r.draw.cls}, {r.draw.kind}, "
                f"outliers {r.draw.outliers:.0%}, "
                f"drops {r.draw.drops:.0%}): {what}"
            )
    return "\n".join(lines)


def _known(d: Score) -> str:
    """Whether the last estimate knew its error: inside or outside its 99 % ellipse, and
    what integrity said."""
    where = "inside" if d.surfacing_d2 <= CHI2_2DOF_99 else "outside"
    return f"{where} its 99 % ellipse, integrity {d.surfacing_integrity or 'unsaid'}"


def redraw(seed: int, n: int, jobs: int, scheduler: str | None) -> int:
    """Is a flagged mission's verdict its conditions', or its one draw of noise's?"""
    noise = [1000 + k for k in range(n)]
    with tempfile.TemporaryDirectory(prefix="navd-mc-") as tmp:
        results = run_all(run_one, [seed] * n, [tmp] * n, noise, jobs=jobs, scheduler=scheduler)
    print(f"`python -m bench.robustness --redraw {seed} --missions {n}`: mission {seed}'s")
    print("conditions with other draws of the sensor and acoustic noise.\n")
    print(
        "| noise seed | default RMS | thesis RMS | default final | thesis final | limit |"
        " default in 95 % | flagged |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for k, r in zip(noise, results, strict=True):
        d, t = r.default, r.thesis
        if d is None or t is None:
            print(f"| {k} | failed: {r.error} |")
            continue
        limit = max(DIVERGED_FINAL_M, 2.0 * t.surfacing_m)
        print(
            f"| {k} | {d.rms_m:.0f} | {t.rms_m:.0f} | {d.surfacing_m:.0f} | "
            f"{t.surfacing_m:.0f} | {limit:.0f} | {d.inside95:.2f} | "
            f"{'yes' if r.diverged else 'no'} |"
        )
    return 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--missions", type=int, default=120)
    p.add_argument(
        "--from",
        dest="first",
        type=int,
        default=1,
        metavar="SEED",
        help="start at this seed: seeds SEED..--missions (missions not flown before)",
    )
    p.add_argument(
        "--jobs", type=int, default=default_jobs(), help="worker processes (default: the cores)"
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the missions on this Dask scheduler's workers instead (tcp://host:8786)",
    )
    p.add_argument("--write", help="BENCHMARKS.md to update")
    p.add_argument(
        "--redraw",
        type=int,
        metavar="SEED",
        help="mission SEED's conditions again, with --missions other draws of sensor noise",
    )
    p.add_argument(
        "--only", choices=list(CLASSES), help="of seeds 1..--missions, those of this class"
    )
    p.add_argument(
        "--kind",
        choices=KINDS,
        help="of seeds 1..--missions, those of this geometry (a moving beacon, or a net of "
        "2 or 3 transponders)",
    )
    p.add_argument("--missions-out", help="write one line per mission (JSON) to this file")
    p.add_argument(
        "--noise-draw",
        type=int,
        default=0,
        metavar="K",
        help="each mission's conditions with its K-th other draw of sensor and acoustic "
        "noise (0: as drawn): how much of a class's figure is one draw's luck",
    )
    p.add_argument(
        "--no-outliers",
        action="store_true",
        help="the same missions without multipath or corrupt beacon positions (what the "
        "bound's ideal outlier detector is worth)",
    )
    p.add_argument(
        "--matched-noise",
        nargs="*",
        choices=list(MATCHED_PARTS),
        metavar="PART",
        help="navd configured with the bound's own model of each mission (its sensor noise, "
        "priors the size of its errors): what the default's conservative noise model costs; "
        f"with PARTs, only those of {', '.join(MATCHED_PARTS)}",
    )
    p.add_argument(
        "--wrong-priors",
        action="store_true",
        help="every mission's config priors on the current, heading bias and speed scale 3 "
        "to 10 times smaller than its errors, as the wrong-prior class's",
    )
    p.add_argument(
        "--wide-ranges",
        action="store_true",
        help="every mission's ranges 1.5 to 3 times noisier than the config's range_std_m",
    )
    p.add_argument(
        "--tide-prediction",
        action="store_true",
        help="the crews of missions whose water has a tide given a prediction of it "
        "(navigation.tide), off by up to a fifth in speed, half an hour and 10 degrees",
    )
    args = p.parse_args()
    matched = None if args.matched_noise is None else tuple(args.matched_noise or MATCHED_PARTS)
    model = (
        ""
        if matched is None
        else (" --matched-noise" + "".join(f" {x}" for x in args.matched_noise))
    )
    if args.redraw is not None:
        return redraw(args.redraw, args.missions, args.jobs, args.scheduler)
    seeds = selected(args.missions, args.only, args.kind, args.first)
    # each mission's files are written and read by the one worker that runs it
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="navd-mc-") as tmp:
        n = len(seeds)
        results = run_all(
            run_one,
            seeds,
            [tmp] * n,
            [noise_seed(s, args.noise_draw) for s in seeds],
            [args.no_outliers] * n,
            [matched] * n,
            [args.wrong_priors] * n,
            [args.wide_ranges] * n,
            [args.tide_prediction] * n,
            jobs=args.jobs,
            scheduler=args.scheduler,
        )
    took = time.perf_counter() - t0
    if args.missions_out:
        with open(args.missions_out, "w", encoding="utf-8") as fh:
            for r in results:
                row = {
                    "seed": r.draw.seed,
                    "class": r.draw.cls,
                    "kind": r.draw.kind,
                    "bound_m": r.bound_m,
                    "error": r.error,
                    "diverged": r.diverged,
                    "against_bound": asdict(r.against) if r.against else None,
                }
                for name, sc in (("default", r.default), ("thesis", r.thesis)):
                    row[name] = asdict(sc) if sc is not None else None
                fh.write(json.dumps(row) + "\n")
    cmd = (
        "`python -m bench.robustness"
        + (f" --from {args.first}" if args.first != 1 else "")
        + f" --missions {args.missions}"
        + (f" --only {args.only}" if args.only else "")
        + (f" --kind {args.kind}" if args.kind else "")
        + (" --no-outliers" if args.no_outliers else "")
        + (f" --noise-draw {args.noise_draw}" if args.noise_draw else "")
        + (" --wrong-priors" if args.wrong_priors else "")
        + (" --wide-ranges" if args.wide_ranges else "")
        + (" --tide-prediction" if args.tide_prediction else "")
        + model
        + "`"
    )
    where = f"Dask at {args.scheduler}" if args.scheduler else f"{args.jobs} worker processes"
    pace = (
        f"Ran in {took / 60:.1f} min on {where} ({took / len(seeds):.2f} s a mission; "
        f"1,000 missions of this mix at this pace: {1000 * took / len(seeds) / 60:.0f} min)."
    )
    report(
        f"{cmd}\n\n{table(results, args.missions, args.first)}\n\n{pace}",
        args.write,
        "bench-robustness"
        + "-no-outliers" * args.no_outliers
        + (f"-noise-draw-{args.noise_draw}" if args.noise_draw else "")
        + "-wrong-priors" * args.wrong_priors
        + "-wide-ranges" * args.wide_ranges
        + "-tide-prediction" * args.tide_prediction
        + model.replace(" --", "-").replace(" ", "-"),
        "Robustness"
        + " without outliers" * args.no_outliers
        + (f", noise draw {args.noise_draw}" if args.noise_draw else "")
        + " with every class's priors too small" * args.wrong_priors
        + " with ranges noisier than the config says" * args.wide_ranges
        + " with the crews' tidal predictions" * args.tide_prediction
        + ("" if matched is None else " with the bound's noise model")
        + (f" ({', '.join(args.matched_noise)} only)" if args.matched_noise else ""),
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
