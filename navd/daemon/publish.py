"""Zenoh publishing: the autopilot's view of navd (schema in docs/zenoh.md).

Key expressions under ``auv/<vehicle>/nav/``:

* ``estimate`` (10 Hz), ``range`` (each range decision), ``health`` (1 Hz): JSON,
  ``application/json`` with schema ``navd/<kind>/1``;
* ``estimate_1hz``: the first estimate of every second, for a radio link;
* ``advisory`` (1 Hz): how well the recent ranges fix each direction (navd/filter/advisory.py);
* ``latest``: a queryable answering with the latest estimate;
* ``alive``: a liveliness token while the daemon runs;
* ``cmd/reset`` and ``cmd/beacon``: queryables for commands, answered ``{"ok": true}``
  or ``{"ok": false, "error": ...}``; a malformed command changes nothing.

Zenoh has no asyncio API: its callbacks run on zenoh threads, and commands are
handed to the event loop with ``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import json
import logging
import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import zenoh

from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.records import BEACON_NAME, SetBeacon, implausible
from navd.schema import SCHEMA_VERSION, Published, to_dict
from navd.settings import ZenohConfig
from navd.validation import Invalid, build, text
from navd.zenohconf import read_zenoh_file

_COMMAND_TIMEOUT_S = 2.0
ZENOH_OPEN_WARN_S = 5.0  # a session not open by then is said in health (it goes on trying)
log = logging.getLogger("navd")
_JSON = zenoh.Encoding.APPLICATION_JSON


def zenoh_config(z: ZenohConfig) -> zenoh.Config:
    """navd's zenoh config: the file, if any, with navd's own keys over it."""
    cfg = read_zenoh_file(z.config_file) if z.config_file else zenoh.Config()
    cfg.insert_json5("mode", json.dumps(z.mode))
    # always set: left unset, a zenoh peer listens on every interface
    cfg.insert_json5("listen/endpoints", json.dumps(z.listen))
    if z.connect:
        cfg.insert_json5("connect/endpoints", json.dumps(z.connect))
    cfg.insert_json5("scouting/multicast/enabled", json.dumps(z.multicast_scouting))
    return cfg


#: ``latest`` answers with an estimate at most this old, else with an error: an
#: estimate from before a silence (a reset, a stalled filter) is not the vehicle's position
LATEST_MAX_AGE_S = 1.0
#: a command is a small JSON object; anything longer is refused before it is parsed
MAX_COMMAND_BYTES = 4096
#: commands of one kind accepted per second on average, and in a burst.  Zenoh gives a
#: queryable no authenticated name of its querier (a query's source_info is the
#: querier's own say), so the budget is per command kind, and only well-formed
#: commands spend it: a flood of malformed ones is answered and costs nothing.
COMMAND_RATE_HZ = 2.0
COMMAND_BURST = 5


@dataclass(frozen=True, slots=True)
class ResetCommand:
    reason: str = text("", r"[^\x00-\x1f]{0,200}", "at most 200 printable characters")
    force: bool = False  # a reset while submerged stops navigation until the next fix


@dataclass(frozen=True, slots=True)
class BeaconCommand:
    # bounds of lat, lon and depth: navd.records.BOUNDS, as for every measured position
    name: str = text("", BEACON_NAME.pattern, "1 to 32 letters, digits, '_', '.' or '-'")
    lat: float = math.nan
    lon: float = math.nan
    depth: float = 0.0


#: a command as the daemon gets it: validated, typed
Command = ResetCommand | BeaconCommand
#: a command's body to its command, or why it is refused
Validator = Callable[[JsonObject], Command | str]


class Outlet(Protocol):
    """What the daemon publishes through: :class:`Publisher`, or a test's stand-in."""

    def put(self, out: Published) -> bytes: ...

    def section(self) -> dict[str, object]: ...

    def forget_latest(self) -> None: ...

    def close(self) -> None: ...


#: opens an outlet in a thread: (the daemon's loop, where commands go) -> the outlet
OutletFactory = Callable[
    [asyncio.AbstractEventLoop, Callable[[Command], str | None]], Outlet
]


def validate_reset(body: JsonObject) -> ResetCommand | str:
    """The reset the body asks for, or why it is refused."""
    try:
        cmd = build(ResetCommand, body)
    except Invalid as exc:
        return str(exc)
    return cmd


def validate_beacon(body: JsonObject) -> BeaconCommand | str:
    """The beacon position the body gives, or why it is refused."""
    missing = [k for k in ("name", "lat", "lon") if k not in body]
    if missing:
        return f"{missing[0]}: missing"
    try:
        cmd = build(BeaconCommand, body)
    except Invalid as exc:
        return str(exc)
    return implausible(SetBeacon(0.0, cmd.name, cmd.lat, cmd.lon, cmd.depth)) or cmd


def encode(seq: int, body: Mapping[str, object]) -> bytes:
    """A message as it goes on zenoh: the schema version, its sequence number, the body."""
    return jsonlines.dumps({"schema": SCHEMA_VERSION, "seq": seq, **body})


class TokenBucket:
    """At most ``rate`` events a second on average, ``burst`` at once."""

    def __init__(self, rate: float, burst: int, clock: Callable[[], float] = time.monotonic):
        self.rate, self.burst, self.clock = rate, float(burst), clock
        self.tokens = float(burst)
        self.t = clock()

    def take(self) -> bool:
        now = self.clock()
        self.tokens = min(self.burst, self.tokens + (now - self.t) * self.rate)
        self.t = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True


def parse_command(raw: bytes, validate: Validator) -> Command | str:
    """The command the bytes ask for, or why it is refused; never raises, whatever they are."""
    if len(raw) > MAX_COMMAND_BYTES:
        return f"payload longer than {MAX_COMMAND_BYTES} bytes"
    try:
        body = jsonlines.loads_unique(raw or b"{}")
    except jsonlines.DuplicateKey as exc:
        return f"key '{str(exc)[:32]}' given twice"
    except (ValueError, RecursionError):  # bad JSON, bad UTF-8, nesting too deep
        return "payload must be a JSON object"
    obj = jsonlines.object_or_none(body)
    if obj is None:
        return "payload must be a JSON object"
    try:
        return validate(obj)
    except Exception:  # pragma: no cover - validators are total; this is the last guard
        return "malformed command"


class Publisher:
    def __init__(
        self,
        zcfg: ZenohConfig,
        vehicle: str,
        loop: asyncio.AbstractEventLoop,
        on_command: Callable[[Command], str | None],
    ) -> None:
        self.prefix = f"auv/{vehicle}/nav"
        self.loop = loop
        self.on_command = on_command
        self.session = zenoh.open(zenoh_config(zcfg))
        s = self.session
        self._pubs = {
            kind: s.declare_publisher(
                f"{self.prefix}/{kind}", encoding=_JSON.with_schema(f"navd/{kind}/{SCHEMA_VERSION}")
            )
            for kind in ("estimate", "range", "health", "advisory")
        }
        # the estimate once a second, for links that cannot carry 10 Hz (a radio modem)
        self._pubs["estimate_1hz"] = s.declare_publisher(
            f"{self.prefix}/estimate_1hz",
            encoding=_JSON.with_schema(f"navd/estimate/{SCHEMA_VERSION}"),
        )
        self._second: float | None = None
        self._latest: Mapping[str, object] | None = None  # the newest estimate, and when it came
        self._t_latest = -math.inf
        self._lock = threading.Lock()
        self._queryables = [
            s.declare_queryable(f"{self.prefix}/latest", self._answer_latest),
            s.declare_queryable(f"{self.prefix}/cmd/reset", self._command("reset", validate_reset)),
            s.declare_queryable(
                f"{self.prefix}/cmd/beacon", self._command("beacon", validate_beacon)
            ),
        ]
        self._token = s.liveliness().declare_token(f"{self.prefix}/alive")
        self.seq = {"estimate": 0, "range": 0, "health": 0, "advisory": 0}
        self.errors = 0
        self.commands = {"accepted": 0, "rejected": 0, "rate_limited": 0}
        self._buckets = {
            kind: TokenBucket(COMMAND_RATE_HZ, COMMAND_BURST) for kind in ("reset", "beacon")
        }

    def section(self) -> dict[str, object]:
        """The open session's part of the daemon's health."""
        return {"open": True, "errors": self.errors, "commands": dict(self.commands)}

    def put(self, out: Published) -> bytes:
        """Publish an output on its key (``auv/<vehicle>/nav/<its type>``)."""
        kind = out.type
        body = to_dict(out)
        self.seq[kind] += 1
        payload = encode(self.seq[kind], body)
        if kind == "estimate":
            with self._lock:
                self._latest, self._t_latest = body, time.monotonic()
            second = math.floor(out.t)
            if second != self._second:
                self._second = second
                with contextlib.suppress(Exception):
                    self._pubs["estimate_1hz"].put(payload)
        try:
            self._pubs[kind].put(payload)
        except Exception:  # a transport hiccup must not stop navigation
            self.errors += 1
        return payload

    def forget_latest(self) -> None:
        """A reset: the estimate before it must not be the answer after it."""
        with self._lock:
            self._latest, self._t_latest = None, -math.inf

    def _answer_latest(self, query: zenoh.Query) -> None:
        with self._lock:
            body, t = self._latest, self._t_latest
        age = time.monotonic() - t
        with contextlib.suppress(Exception):
            if body is None or age > LATEST_MAX_AGE_S:
                why = "none since a reset" if body is None else f"the last is {age:.1f} s old"
                query.reply_err(jsonlines.dumps({"error": f"no current estimate ({why})"}))
                return
            # its age when sent: the querier's clock need not be the vehicle's
            payload = encode(self.seq["estimate"], {**body, "age_s": round(age, 3)})
            query.reply(f"{self.prefix}/latest", payload, encoding=_JSON)

    def _command(
        self, name: str, validate: Validator
    ) -> Callable[[zenoh.Query], None]:
        def handle(query: zenoh.Query) -> None:
            reply: dict[str, object]
            try:
                reply = self._decide(name, validate, query)
            except Exception as exc:  # nothing may be left unanswered in zenoh's thread
                reply = {"ok": False, "error": f"malformed command ({exc.__class__.__name__})"}
            if not reply["ok"]:
                self.commands["rejected"] += 1
            with contextlib.suppress(Exception):
                query.reply(str(query.key_expr), jsonlines.dumps(reply), encoding=_JSON)

        return handle

    def _decide(
        self, name: str, validate: Validator, query: zenoh.Query
    ) -> dict[str, object]:
        raw = query.payload.to_bytes() if query.payload is not None else b"{}"
        cmd = parse_command(raw, validate)
        if isinstance(cmd, str):
            return {"ok": False, "error": cmd}  # answered, and no well-formed one's budget
        if not self._buckets[name].take():
            self.commands["rate_limited"] += 1
            return {"ok": False, "error": "rate limited: try again later"}
        # the daemon's state decides the rest (a reset while submerged, the beacon
        # table full): ask the event loop and wait for its answer
        fut: concurrent.futures.Future[str | None] = concurrent.futures.Future()

        def run() -> None:
            try:
                fut.set_result(self.on_command(cmd))
            except Exception as exc:
                fut.set_exception(exc)

        self.loop.call_soon_threadsafe(run)
        try:
            err = fut.result(timeout=_COMMAND_TIMEOUT_S)
        except concurrent.futures.TimeoutError:
            return {"ok": False, "error": "the daemon did not answer in time"}
        if err:
            return {"ok": False, "error": err}
        self.commands["accepted"] += 1
        return {"ok": True}

    def close(self) -> None:
        try:
            self._token.undeclare()
            for q in self._queryables:
                q.undeclare()
            for p in self._pubs.values():
                p.undeclare()
        finally:
            self.session.close()


async def open_with_retry(
    factory: OutletFactory,
    on_command: Callable[[Command], str | None],
    say: Callable[[str], None],
) -> Outlet:
    """The publisher ``factory`` makes, tried until it opens (port in use, bad endpoint,
    a router that does not answer); ``say`` is told why it is not open yet, and "" once
    it is.  Navigation and the log do not wait for it."""
    loop = asyncio.get_running_loop()
    delay = 1.0
    while True:
        try:
            # zenoh.open blocks (name resolution, a slow file, a router that does not
            # answer): in a thread, so that navigation never waits for it
            opening = asyncio.ensure_future(asyncio.to_thread(factory, loop, on_command))
            while not opening.done():
                await asyncio.wait({opening}, timeout=ZENOH_OPEN_WARN_S)
                if not opening.done():
                    say(f"still opening after {ZENOH_OPEN_WARN_S:g} s")
            pub = opening.result()
            say("")
            log.info("zenoh session open")
            return pub
        except Exception as exc:  # zenoh raises its own ZError, and OSError
            if delay == 1.0:
                log.error("zenoh: cannot open the session (%s); retrying", exc)
            say(f"{exc.__class__.__name__}: {exc}"[:200])
            await asyncio.sleep(delay)
            delay = min(30.0, delay * 2)
