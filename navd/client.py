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
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from navd.formats import jsonlines
from navd.schema import Advisory, Estimate, RangeDecision, from_dict

__all__ = ["Answer", "NavClient", "NavFleet", "open_session"]


@dataclass(frozen=True, slots=True)
class Answer:
    """The daemon's answer to a command: ``ok``, or why not."""

    ok: bool
    error: str = ""


def open_session(connect: list[str] | None = None, config: zenoh.Config | None = None):
    """A zenoh client of ``connect`` (the daemon, or a router), with scouting off.

    A client talks only to what it connects to: everything it receives on navd's keys
    has passed the access control of navd's session (or the router's).  A peer would
    also connect to any peer that gossip told it of, and take what that one put."""
    cfg = config or zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("scouting/gossip/enabled", "false")
    if connect:
        cfg.insert_json5("connect/endpoints", jsonlines.dumps(list(connect)).decode())
    return zenoh.open(cfg)


def _decode(payload: Any) -> dict[str, Any] | None:
    try:
        obj = jsonlines.loads(payload.to_bytes())
    except jsonlines.DecodeError:
        return None
    return obj if isinstance(obj, dict) else None


def _typed(cls: Any, payload: Any) -> Any:
    """The payload as ``cls``, or None for what is not navd's schema (another
    publisher under the same keys must not raise in zenoh's thread)."""
    d = _decode(payload)
    if d is None:
        return None
    try:
        return from_dict(cls, d)
    except TypeError:  # a field the schema requires is missing
        return None


def _typed_callback(cls: Any, callback: Callable[[Any], None]) -> Callable[[Any], None]:
    def on_sample(sample: Any) -> None:
        x = _typed(cls, sample.payload)
        if x is not None:
            callback(x)

    return on_sample


def endpoints(listen: list[str], connect: list[str], asked: list[str] | None) -> list[str]:
    """Where a tool connects: where it was told, else where the daemon connects (a
    router), else where the daemon listens."""
    return list(asked or connect or listen)


class NavClient:
    """One vehicle's navigation over zenoh (keys in docs/zenoh.md)."""

    def __init__(
        self,
        vehicle: str,
        connect: list[str] | None = None,
        session: Any = None,
        timeout_s: float = 2.0,
        config: zenoh.Config | None = None,
    ) -> None:
        """``config``: a zenoh config (e.g. with the user and password of
        config/zenoh.json5's access control); ``session``: an open session to share."""
        self.vehicle = vehicle
        self.prefix = f"auv/{vehicle}/nav"
        self.timeout_s = timeout_s
        self._own = session is None
        self.session = session if session is not None else open_session(connect, config)
        self._subs: list[Any] = []

    def __enter__(self) -> NavClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for s in self._subs:
            with contextlib.suppress(Exception):
                s.undeclare()
        self._subs.clear()
        if self._own:
            self.session.close()

    # -- reading -------------------------------------------------------------------
    def latest(self) -> Estimate | None:
        """The daemon's newest estimate (its ``latest`` queryable), or None."""
        for reply in self.session.get(f"{self.prefix}/latest", timeout=self.timeout_s):
            if reply.ok is not None:
                e = _typed(Estimate, reply.ok.payload)
                if e is not None:
                    return e
        return None

    def subscribe(
        self,
        on_estimate: Callable[[Estimate], None] | None = None,
        on_range: Callable[[RangeDecision], None] | None = None,
        on_advisory: Callable[[Advisory], None] | None = None,
    ) -> None:
        """Call back on every estimate (10 Hz), range decision and observability
        advisory (1 Hz), on a zenoh thread."""
        for kind, cls, callback in (
            ("estimate", Estimate, on_estimate),
            ("range", RangeDecision, on_range),
            ("advisory", Advisory, on_advisory),
        ):
            if callback is not None:
                self._subs.append(
                    self.session.declare_subscriber(
                        f"{self.prefix}/{kind}", _typed_callback(cls, callback)
                    )
                )

    async def estimates(self, maxsize: int = 64) -> AsyncIterator[Estimate]:
        """Every estimate, in the event loop; the oldest are dropped if it falls behind."""
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[Estimate] = asyncio.Queue(maxsize)

        def put(e: Estimate) -> None:
            if queue.full():
                queue.get_nowait()
            queue.put_nowait(e)

        def hand_over(e: Estimate) -> None:
            loop.call_soon_threadsafe(put, e)

        self.subscribe(hand_over)
        while True:
            yield await queue.get()

    @property
    def alive(self) -> bool:
        """Is the daemon up (its liveliness token is there)?  A session opened a moment
        ago may not have learnt the routes yet: ask again before concluding it is down."""
        replies = self.session.liveliness().get(f"{self.prefix}/alive", timeout=self.timeout_s)
        return any(r.ok is not None for r in replies)

    # -- commands --------------------------------------------------------------------
    def reset(self, force: bool = False, reason: str = "") -> Answer:
        """Forget the estimate; it starts again at the next fix (``force`` when submerged)."""
        body: dict[str, Any] = {"force": force}
        if reason:
            body["reason"] = reason
        return self._command("reset", body)

    def set_beacon(self, name: str, lat: float, lon: float, depth: float = 0.0) -> Answer:
        """A fixed position for a beacon whose replies carry none."""
        return self._command("beacon", {"name": name, "lat": lat, "lon": lon, "depth": depth})

    def _command(self, name: str, body: dict[str, Any]) -> Answer:
        replies = self.session.get(
            f"{self.prefix}/cmd/{name}", payload=jsonlines.dumps(body), timeout=self.timeout_s
        )
        for reply in replies:
            if reply.ok is not None:
                d = _decode(reply.ok.payload) or {}
                return Answer(bool(d.get("ok")), str(d.get("error", "")))
            return Answer(False, f"zenoh: {reply.err.payload.to_string()}")
        return Answer(False, "no answer (is the daemon up, and may this session command it?)")


class NavFleet:
    """Every vehicle's estimates under ``auv/*``, and which daemons are alive."""

    def __init__(
        self,
        connect: list[str] | None = None,
        session: Any = None,
        config: zenoh.Config | None = None,
    ) -> None:
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
    def _vehicle(key: Any) -> str:
        return str(key).split("/")[1]

    def _on_estimate(self, sample: Any) -> None:
        e = _typed(Estimate, sample.payload)
        if e is not None:
            self.latest[self._vehicle(sample.key_expr)] = e

    def _on_alive(self, sample: Any) -> None:
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
