"""The navigation state on disk, once a second, for a restart while submerged.

systemd restarts navd when the watchdog fires or it crashes; without this the
restarted daemon would wait for a GPS fix, blind for the rest of the dive.  The
file is small JSON, replaced atomically (written beside it, flushed, renamed over
it), in systemd's ``StateDirectory`` (``/var/lib/navd``).  On start, a checkpoint
of this vehicle and this navigation config, younger than ``checkpoint.max_age_s``,
is resumed (navd/filter/navigator.py, ``Resume``); anything else is passed over
with one line saying why.
"""

from __future__ import annotations

import asyncio
import dataclasses
import hashlib
import logging
import math
import os
import time
import typing
from collections.abc import Callable, Mapping
from pathlib import Path

from navd import files
from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.records import Resume, implausible
from navd.settings import Config

FORMAT = "navd-checkpoint"
VERSION = 1
NAME = "checkpoint.json"
MAX_BYTES = 64 * 1024
log = logging.getLogger("navd")


def checkpoint_dir(cfg: Config, env: typing.Mapping[str, str]) -> Path | None:
    """``checkpoint.dir``, else systemd's StateDirectory, else none (a development run)."""
    d = cfg.checkpoint.dir or env.get("STATE_DIRECTORY", "").split(":")[0]
    return Path(d) if d else None


def config_digest(cfg: Config) -> str:
    """What a checkpoint must have been made under: the navigation config and beacons."""
    doc = {
        "navigation": dataclasses.asdict(cfg.navigation),
        "beacons": {k: dataclasses.asdict(b) for k, b in sorted(cfg.beacons.items())},
    }
    return hashlib.sha256(jsonlines.dumps(doc)).hexdigest()[:16]


class Checkpoints:
    def __init__(
        self, directory: Path, vehicle: str, digest: str, wall: Callable[[], float] = time.time
    ) -> None:
        self.path = directory / NAME
        self.vehicle = vehicle
        self.digest = digest
        self.wall = wall
        self.written = 0
        self.errors = 0
        self.last_error = ""

    def write(self, snapshot: Mapping[str, object]) -> bool:
        doc = {
            "format": FORMAT,
            "version": VERSION,
            "vehicle": self.vehicle,
            "config": self.digest,
            "utc": self.wall(),
            **snapshot,
        }
        tmp = self.path.with_name(NAME + ".part")
        try:
            with open(tmp, "wb") as fh:
                fh.write(jsonlines.dumps(doc))
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path)
        except OSError as exc:  # a full or read-only disk: said in health, navigation goes on
            self.errors += 1
            self.last_error = f"{exc.strerror or exc.__class__.__name__}"
            return False
        self.written += 1
        return True

    def section(self, resumed: Mapping[str, object] | None) -> dict[str, object]:
        """The checkpoints' part of the daemon's health, with what this run resumed from."""
        return {
            "file": str(self.path),
            "written": self.written,
            "errors": self.errors,
            "last_error": self.last_error,
            "resumed": resumed,
        }

    def load(self, max_age_s: float) -> tuple[JsonObject | None, str]:
        """The checkpoint to resume, with its ``age_s``, or None and one line why not
        (empty when there is none at all)."""
        if not self.path.exists():
            return None, ""
        try:
            doc = jsonlines.object_or_none(
                jsonlines.loads(files.read_regular(self.path, MAX_BYTES))
            )
        except files.FileRefused as exc:
            return None, f"checkpoint ignored: {exc}"
        except jsonlines.DecodeError:
            return None, f"checkpoint ignored: {self.path}: not JSON"
        if doc is None or doc.get("format") != FORMAT:
            return None, f"checkpoint ignored: {self.path}: not a navd checkpoint"
        if doc.get("version") != VERSION:
            return None, f"checkpoint ignored: {self.path}: version {doc.get('version')!r:.10}"
        if doc.get("vehicle") != self.vehicle:
            return None, f"checkpoint ignored: of another vehicle ({str(doc.get('vehicle'))[:32]})"
        if doc.get("config") != self.digest:
            return None, "checkpoint ignored: made under another navigation config"
        utc = doc.get("utc")
        if isinstance(utc, bool) or not isinstance(utc, int | float) or not math.isfinite(utc):
            return None, f"checkpoint ignored: {self.path}: no time"
        age = self.wall() - utc
        if age < -1.0:
            return None, f"checkpoint ignored: from {-age:.0f} s in the future (the clock?)"
        if age > max_age_s:
            return None, f"checkpoint ignored: {age:.0f} s old (checkpoint.max_age_s {max_age_s:g})"
        return {**doc, "age_s": max(0.0, age)}, ""


def number_or_none(v: object) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _number(v: object) -> float:
    x = number_or_none(v)
    if x is None:
        raise TypeError("not a number")
    return x


def _numbers(v: object) -> tuple[float, ...]:
    if not isinstance(v, list):
        raise TypeError("not a list")
    return tuple(_number(x) for x in v)


def _held_or_none(v: object, n: int) -> tuple[float, ...] | None:
    """``n`` numbers as the filter held them (a beacon outage, how often replies read
    long), or None for anything else: the restart then starts that part afresh, as
    before checkpoints held it."""
    try:
        held = _numbers(v)
    except TypeError:
        return None
    return held if len(held) == n else None


def _pair(v: tuple[float, ...] | None) -> tuple[float, float] | None:
    return None if v is None else (v[0], v[1])


def resume_record(snap: JsonObject, t: float) -> Resume | str:
    """The record that resumes navigation at ``t`` from a loaded checkpoint, or why it
    cannot (the filter still judges the state itself)."""
    try:
        rec = Resume(
            t,
            str(snap["mode"]),
            _numbers(snap["x"]),
            _numbers(snap["P"]),
            _number(snap["age_s"]),
            number_or_none(snap.get("surface_bar")),
            number_or_none(snap.get("surface_alt")),
            number_or_none(snap.get("depth_m")),
            number_or_none(snap.get("range_scale")),
            number_or_none(snap.get("range_scale_var")),
            _held_or_none(snap.get("beacon_outage"), 8),
            _pair(_held_or_none(snap.get("long_refused"), 2)),
            _held_or_none(snap.get("range_noise"), 4),
        )
    except (KeyError, TypeError, ValueError):
        return "fields missing or not numbers"
    return implausible(rec) or rec


def resume(
    store: Checkpoints,
    max_age_s: float,
    t: float,
    feed: Callable[[Resume], None],
    counters: typing.Mapping[str, int],
) -> dict[str, object] | None:
    """Navigate on from the store's checkpoint, if it is of this vehicle and config and
    young enough: its record is fed (and so logged, and a replay resumes the same).
    Returns what was resumed, for health; None, with one line in the journal, if not."""
    snap, said = store.load(max_age_s)
    if snap is None:
        if said:
            log.warning("%s", said)
        return None
    rec = resume_record(snap, t)
    if isinstance(rec, str):
        log.warning("checkpoint ignored: %s: %s", store.path, rec)
        return None
    feed(rec)
    if not counters.get("resumed"):
        log.warning("checkpoint ignored: the filter refused it (%s)", dict(counters))
        return None
    log.info("resumed navigation from a checkpoint %.0f s old", rec.age_s)
    return {
        "t": t,
        "age_s": round(rec.age_s, 1),
        "lat": number_or_none(snap.get("lat")),
        "lon": number_or_none(snap.get("lon")),
    }


async def keep_writing(
    store: Checkpoints, every_s: float, snapshot: Callable[[], Mapping[str, object] | None]
) -> None:
    """A checkpoint every ``every_s``, while the daemon runs."""
    while True:
        await asyncio.sleep(every_s)
        snap = snapshot()  # taken here, between two ticks: one consistent state
        if snap is not None:
            # the write ends in an fsync, which an SD card can take 100 ms over
            await asyncio.to_thread(store.write, snap)
