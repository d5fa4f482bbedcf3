"""``navd.client``: what an autopilot imports instead of parsing navd's JSON.

::

    from navd.client import NavClient

    with NavClient("690s", connect=["tcp/192.168.2.10:7447"]) as nav:
        e = nav.latest()                      # the newest estimate, or None
        nav.subscribe(lambda e: print(e.lat, e.lon, e.integrity))
        answer = nav.set_beacon("udb", 37.05, -80.66, depth=3.0)

Estimates and range decisions are the dataclasses of :mod:`navd.schema`.  Zenoh
calls back on its own threads; :meth:`NavClient.estimates` hands them to asyncio.
A :class:`NavFleet` watches every vehicle under ``auv/*``, and which are alive.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import AsyncIterator, Callable, Mapping
from dataclasses import dataclass

import zenoh

from navd.formats import jsonlines
from navd.formats.jsonlines import JsonObject
from navd.schema import Advisory, Estimate, RangeDecision, T, from_dict
from navd.zenohconf import read_zenoh_file

__all__ = [
    "Answer",
    "Gone",
    "NavClient",
    "NavFleet",
    "NavUnavailable",
    "NoAnswer",
    "Stale",
    "open_session",
]


@dataclass(frozen=True, slots=True)
class Answer:
    """The daemon's answer to a command: ``ok``, or why not."""

    ok: bool
    error: str = ""


#: how long a client keeps trying to reach navd (or the router) when it opens
OPEN_WAIT_S = 10.0


def open_session(
    connect: list[str] | None = None,
    config: zenoh.Config | None = None,
    wait_s: float = OPEN_WAIT_S,
) -> zenoh.Session:
    """A zenoh client of ``connect`` (the daemon, or a router), with scouting off.

    A client talks only to what it connects to: everything it receives on navd's keys
    has passed the access control of navd's session (or the router's).  A peer would
    also connect to any peer that gossip told it of, and take what that one put.  It
    keeps trying to connect for ``wait_s`` (a tool started before navd), unless its
    zenoh file says otherwise, then raises ``zenoh.ZError``."""
    cfg = config or zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("scouting/gossip/enabled", "false")
    try:
        given = jsonlines.loads(cfg.get_json("connect/timeout_ms"))
    except Exception:  # zenoh raises for a key that is not set
        given = None
    if given is None:
        cfg.insert_json5("connect/timeout_ms", str(int(wait_s * 1000)))
    if connect:
        cfg.insert_json5("connect/endpoints", jsonlines.dumps(list(connect)).decode())
    return zenoh.open(cfg)


def _decode(payload: zenoh.ZBytes) -> JsonObject | None:
    try:
        return jsonlines.object_or_none(jsonlines.loads(payload.to_bytes()))
    except jsonlines.DecodeError:
        return None


def _typed(cls: type[T], payload: zenoh.ZBytes) -> T | None:
    """The payload as ``cls``, or None for what is not navd's schema (another
    publisher under the same keys must not raise in zenoh's thread)."""
    d = _decode(payload)
    if d is None:
        return None
    try:
        return from_dict(cls, d)
    except TypeError:  # a field the schema requires is missing
        return None


def _typed_callback(
    cls: type[T], callback: Callable[[T], None]
) -> Callable[[zenoh.Sample], None]:
    def on_sample(sample: zenoh.Sample) -> None:
        x = _typed(cls, sample.payload)
        if x is not None:
            callback(x)

    return on_sample


def endpoints(listen: list[str], connect: list[str], asked: list[str] | None) -> list[str]:
    """Where a tool connects: where it was told, else where the daemon connects (a
    router), else where the daemon listens."""
    return list(asked or connect or listen)


class NavUnavailable(Exception):
    """navd cannot be heard: what an autopilot must treat as "no position".  One line."""


class Stale(NavUnavailable):
    """No estimate within the staleness bound (navd stalled, reset, or the link is down)."""


class Gone(NavUnavailable):
    """navd's liveliness token went away: the daemon stopped, or its session died."""


class NoAnswer(NavUnavailable):
    """Nothing answered in time: navd is down, or this session may not read it."""


def _user(config: zenoh.Config | None) -> str | None:
    if config is None:
        return None
    try:
        user = jsonlines.loads(config.get_json("transport/auth/usrpwd/user"))
    except Exception:  # not set: zenoh says so by raising
        return None
    return user if isinstance(user, str) else None


def _session_or_why(
    connect: list[str] | None, config: zenoh.Config | None, wait_s: float, user: str | None
) -> zenoh.Session:
    """A session to navd, or :class:`NavUnavailable` saying what to look at."""
    try:
        return open_session(connect, config, wait_s)
    except zenoh.ZError as exc:
        ask = "is navd listening there"
        if user:
            ask += f", and does it know user '{user}' with this password"
        raise NavUnavailable(
            f"cannot open a zenoh session to {', '.join(connect or []) or 'navd'}: "
            f"{str(exc).split(' at /')[0][:120]} ({ask}?)"
        ) from None


class NavClient:
    """One vehicle's navigation over zenoh (keys in docs/zenoh.md), failing safe.

    Everything it hands over is current: :meth:`latest` returns None rather than an
    estimate older than ``stale_s`` or from before a reset; :meth:`estimates` raises
    :class:`Stale` when no estimate came within ``stale_s`` and :class:`Gone` when
    navd's liveliness token goes; :meth:`subscribe` reports the same to
    ``on_unavailable``.  An autopilot treats all three, and integrity ``lost``, as
    "position unknown" (docs/zenoh.md, "What the client guarantees").
    """

    def __init__(
        self,
        vehicle: str,
        connect: list[str] | None = None,
        session: zenoh.Session | None = None,
        timeout_s: float = 2.0,
        config: zenoh.Config | None = None,
        config_file: str | None = None,
        stale_s: float = 1.0,
        open_wait_s: float = OPEN_WAIT_S,
    ) -> None:
        """``config`` or ``config_file``: a zenoh config (the user and password of
        config/zenoh.json5's access control, TLS); ``session``: an open session to
        share.  ``stale_s``: an estimate older than this is no position (10 Hz: 1 s).
        ``open_wait_s``: how long to keep trying to reach navd at the start."""
        self.vehicle = vehicle
        self.prefix = f"auv/{vehicle}/nav"
        self.timeout_s = timeout_s
        self.stale_s = stale_s
        self.connect = list(connect or [])
        if config_file is not None:
            config = read_zenoh_file(config_file, "zenoh config")
        self.user = _user(config)
        self._own = session is None
        self.session = session or _session_or_why(connect, config, open_wait_s, self.user)
        self._subs: list[zenoh.Subscriber[None]] = []
        self._watchdogs: list[threading.Event] = []

    def __enter__(self) -> NavClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for stop in self._watchdogs:
            stop.set()
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.undeclare()
        self._subs.clear()
        if self._own:
            self.session.close()

    def _no_answer(self) -> NoAnswer:
        who = f"user '{self.user}'" if self.user else "this session (no user)"
        via = f" via {', '.join(self.connect)}" if self.connect else ""
        return NoAnswer(
            f"no answer from {self.prefix}{via} within {self.timeout_s:g} s: is navd up, "
            f"and may {who} read it?"
        )

    # -- reading -------------------------------------------------------------------
    def latest(self, max_age_s: float | None = None) -> Estimate | None:
        """The daemon's newest estimate, if it is at most ``max_age_s`` (default
        ``stale_s``) old; None otherwise, and None if there is none since a reset."""
        bound = self.stale_s if max_age_s is None else max_age_s
        for reply in self.session.get(f"{self.prefix}/latest", timeout=self.timeout_s):
            if reply.ok is None:
                continue  # navd said why it has none (stale, reset)
            d = _decode(reply.ok.payload)
            age = d.get("age_s") if d is not None else None
            if isinstance(age, bool) or not isinstance(age, int | float) or not 0 <= age <= bound:
                continue  # no age (not navd's answer) or too old
            e = _typed(Estimate, reply.ok.payload)
            if e is not None:
                return e
        return None

    def check(self) -> None:
        """Raise :class:`NoAnswer`, saying what to look at, unless navd answers."""
        for reply in self.session.get(f"{self.prefix}/latest", timeout=self.timeout_s):
            if reply.ok is not None or reply.err is not None:
                return
        raise self._no_answer()

    def subscribe(
        self,
        on_estimate: Callable[[Estimate], None] | None = None,
        on_range: Callable[[RangeDecision], None] | None = None,
        on_advisory: Callable[[Advisory], None] | None = None,
        on_unavailable: Callable[[NavUnavailable], None] | None = None,
    ) -> None:
        """Call back on every estimate (10 Hz), range decision and observability
        advisory (1 Hz), on a zenoh thread; and ``on_unavailable`` with :class:`Stale`
        or :class:`Gone` when estimates stop for ``stale_s`` or navd goes (once per
        silence, again after estimates have come back)."""
        last = [time.monotonic()]
        if on_unavailable is not None and on_estimate is not None:
            user_cb = on_estimate

            def on_estimate(e: Estimate) -> None:
                last[0] = time.monotonic()
                user_cb(e)

        self._listen("estimate", Estimate, on_estimate)
        self._listen("range", RangeDecision, on_range)
        self._listen("advisory", Advisory, on_advisory)
        if on_unavailable is not None:
            self._watch(last, on_unavailable)

    def _listen(self, kind: str, cls: type[T], callback: Callable[[T], None] | None) -> None:
        if callback is not None:
            self._subs.append(
                self.session.declare_subscriber(
                    f"{self.prefix}/{kind}", _typed_callback(cls, callback)
                )
            )

    def _watch(self, last: list[float], report: Callable[[NavUnavailable], None]) -> None:
        stop = threading.Event()
        self._watchdogs.append(stop)
        said = [0.0]  # the estimate time last reported as stale or gone

        def gone(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE and said[0] != last[0]:
                said[0] = last[0]
                report(Gone(f"{self.prefix}: navd's liveliness token went away"))

        self._subs.append(
            self.session.liveliness().declare_subscriber(f"{self.prefix}/alive", gone)
        )

        def run() -> None:
            while not stop.wait(min(0.1, self.stale_s / 4)):
                quiet = time.monotonic() - last[0]
                if quiet > self.stale_s and said[0] != last[0]:
                    said[0] = last[0]
                    report(Stale(f"{self.prefix}: no estimate for {quiet:.1f} s"))

        threading.Thread(target=run, name=f"navd-client {self.prefix}", daemon=True).start()

    async def estimates(
        self, maxsize: int = 64, stale_s: float | None = None
    ) -> AsyncIterator[Estimate]:
        """Every estimate, in the event loop; the oldest are dropped if it falls behind.

        Raises :class:`Stale` when none came within ``stale_s`` (default the client's),
        and :class:`Gone` when navd's liveliness token goes: the loop never waits on a
        dead daemon."""
        bound = self.stale_s if stale_s is None else stale_s
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[Estimate | NavUnavailable] = asyncio.Queue(maxsize)

        def put(x: Estimate | NavUnavailable) -> None:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(x)

        def on_estimate(e: Estimate) -> None:
            loop.call_soon_threadsafe(put, e)

        def on_alive(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE:
                loop.call_soon_threadsafe(
                    put, Gone(f"{self.prefix}: navd's liveliness token went away")
                )

        subs = [
            self.session.declare_subscriber(
                f"{self.prefix}/estimate", _typed_callback(Estimate, on_estimate)
            ),
            self.session.liveliness().declare_subscriber(f"{self.prefix}/alive", on_alive),
        ]
        try:
            while True:
                try:
                    x = await asyncio.wait_for(queue.get(), bound)
                except TimeoutError:
                    raise Stale(f"{self.prefix}: no estimate for {bound:g} s") from None
                if isinstance(x, NavUnavailable):
                    raise x
                yield x
        finally:
            for s in subs:
                with contextlib.suppress(Exception):
                    s.undeclare()

    @property
    def alive(self) -> bool:
        """Is the daemon up (its liveliness token is there)?  A session opened a moment
        ago may not have learnt the routes yet: ask again before concluding it is down."""
        replies = self.session.liveliness().get(f"{self.prefix}/alive", timeout=self.timeout_s)
        return any(r.ok is not None for r in replies)

    # -- commands --------------------------------------------------------------------
    def reset(self, force: bool = False, reason: str = "") -> Answer:
        """Forget the estimate; it starts again at the next fix (``force`` when submerged)."""
        body: dict[str, object] = {"force": force}
        if reason:
            body["reason"] = reason
        return self._command("reset", body)

    def set_beacon(self, name: str, lat: float, lon: float, depth: float = 0.0) -> Answer:
        """A fixed position for a beacon whose replies carry none."""
        return self._command("beacon", {"name": name, "lat": lat, "lon": lon, "depth": depth})

    def _command(self, name: str, body: Mapping[str, object]) -> Answer:
        replies = self.session.get(
            f"{self.prefix}/cmd/{name}", payload=jsonlines.dumps(body), timeout=self.timeout_s
        )
        for reply in replies:
            if reply.ok is not None:
                d = _decode(reply.ok.payload) or {}
                return Answer(bool(d.get("ok")), str(d.get("error", "")))
            why = reply.err.payload.to_string() if reply.err is not None else "an empty reply"
            return Answer(False, f"zenoh: {why}")
        who = f"user '{self.user}'" if self.user else "this session (no user)"
        return Answer(False, f"no answer from {self.prefix}: is navd up, and may {who} command it?")


class NavFleet:
    """Every vehicle's estimates under ``auv/*``, and which daemons are alive."""

    def __init__(
        self,
        connect: list[str] | None = None,
        session: zenoh.Session | None = None,
        config: zenoh.Config | None = None,
        config_file: str | None = None,
    ) -> None:
        if config_file is not None:
            config = read_zenoh_file(config_file, "zenoh config")
        self._own = session is None
        self.session = session if session is not None else open_session(connect, config)
        self.latest: dict[str, Estimate] = {}
        self.up: set[str] = set()
        self._subs = [
            self.session.declare_subscriber("auv/*/nav/estimate", self._on_estimate),
            self.session.liveliness().declare_subscriber(
                "auv/*/nav/alive", self._on_alive, history=True
            ),
        ]

    @staticmethod
    def _vehicle(key: zenoh.KeyExpr) -> str:
        return str(key).split("/")[1]

    def _on_estimate(self, sample: zenoh.Sample) -> None:
        e = _typed(Estimate, sample.payload)
        if e is not None:
            self.latest[self._vehicle(sample.key_expr)] = e

    def _on_alive(self, sample: zenoh.Sample) -> None:
        name = self._vehicle(sample.key_expr)
        if sample.kind == zenoh.SampleKind.PUT:
            self.up.add(name)
        else:
            self.up.discard(name)

    def close(self) -> None:
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.undeclare()
        if self._own:
            self.session.close()
