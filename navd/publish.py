"""Zenoh publishing: the autopilot's view of navd (schema in docs/zenoh.md).

Key expressions under ``auv/<vehicle>/nav/``:

* ``estimate`` (10 Hz), ``range`` (each range decision), ``health`` (1 Hz): JSON,
  ``application/json`` with schema ``navd/<kind>/1``;
* ``latest``: a queryable answering with the latest estimate;
* ``alive``: a liveliness token while the daemon runs;
* ``cmd/reset`` and ``cmd/beacon``: queryables for commands, answered ``{"ok": true}``
  or ``{"ok": false, "error": ...}``; a malformed command changes nothing.

Zenoh has no asyncio API: its callbacks run on zenoh threads, and commands are
handed to the event loop with ``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
import json
import math
import threading
from collections.abc import Callable
from typing import Any

import zenoh

from navd.config import ZenohConfig

SCHEMA_VERSION = 1
_JSON = zenoh.Encoding.APPLICATION_JSON


def zenoh_config(z: ZenohConfig) -> zenoh.Config:
    cfg = zenoh.Config.from_file(z.config_file) if z.config_file else zenoh.Config()
    cfg.insert_json5("mode", json.dumps(z.mode))
    if z.listen:
        cfg.insert_json5("listen/endpoints", json.dumps(z.listen))
    if z.connect:
        cfg.insert_json5("connect/endpoints", json.dumps(z.connect))
    cfg.insert_json5("scouting/multicast/enabled", json.dumps(z.multicast_scouting))
    return cfg


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def validate_reset(body: dict[str, Any]) -> str | None:
    extra = set(body) - {"reason"}
    if extra:
        return f"unknown field {sorted(extra)[0]!r}"
    if "reason" in body and not isinstance(body["reason"], str):
        return "field 'reason' must be a string"
    return None


def validate_beacon(body: dict[str, Any]) -> str | None:
    extra = set(body) - {"name", "lat", "lon", "depth"}
    if extra:
        return f"unknown field {sorted(extra)[0]!r}"
    if not isinstance(body.get("name"), str) or not body["name"]:
        return "field 'name' must be a non-empty string"
    for key, lo, hi in (("lat", -90.0, 90.0), ("lon", -180.0, 180.0), ("depth", 0.0, 11000.0)):
        if key == "depth" and key not in body:
            continue
        v = body.get(key)
        if not _finite(v):
            return f"field '{key}' must be a finite number"
        if not lo <= v <= hi:
            return f"field '{key}'={v} outside [{lo:g}, {hi:g}]"
    return None


class Publisher:
    def __init__(
        self,
        zcfg: ZenohConfig,
        vehicle: str,
        loop: asyncio.AbstractEventLoop,
        on_command: Callable[[str, dict[str, Any]], None],
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
            for kind in ("estimate", "range", "health")
        }
        self._latest: bytes = b"null"
        self._lock = threading.Lock()
        self._queryables = [
            s.declare_queryable(f"{self.prefix}/latest", self._answer_latest),
            s.declare_queryable(f"{self.prefix}/cmd/reset", self._command("reset", validate_reset)),
            s.declare_queryable(
                f"{self.prefix}/cmd/beacon", self._command("beacon", validate_beacon)
            ),
        ]
        self._token = s.liveliness().declare_token(f"{self.prefix}/alive")
        self.seq = {"estimate": 0, "range": 0, "health": 0}
        self.errors = 0
        self.commands = {"accepted": 0, "rejected": 0}

    def put(self, kind: str, body: dict[str, Any]) -> bytes:
        self.seq[kind] += 1
        payload = json.dumps(
            {"schema": SCHEMA_VERSION, "seq": self.seq[kind], **body},
            separators=(",", ":"),
            allow_nan=False,
        ).encode()
        if kind == "estimate":
            with self._lock:
                self._latest = payload
        try:
            self._pubs[kind].put(payload)
        except Exception:  # a transport hiccup must not stop navigation
            self.errors += 1
        return payload

    def _answer_latest(self, query: zenoh.Query) -> None:
        with self._lock:
            payload = self._latest
        query.reply(f"{self.prefix}/latest", payload, encoding=_JSON)

    def _command(self, name: str, validate: Callable[[dict[str, Any]], str | None]):
        def handle(query: zenoh.Query) -> None:
            raw = query.payload.to_bytes() if query.payload is not None else b"{}"
            try:
                body = json.loads(raw or b"{}")
            except (json.JSONDecodeError, UnicodeDecodeError):
                body = None
            err = "payload must be a JSON object" if not isinstance(body, dict) else None
            err = err or validate(body)
            if err:
                self.commands["rejected"] += 1
                reply = {"ok": False, "error": err}
            else:
                self.commands["accepted"] += 1
                self.loop.call_soon_threadsafe(self.on_command, name, body)
                reply = {"ok": True}
            query.reply(str(query.key_expr), json.dumps(reply).encode(), encoding=_JSON)

        return handle

    def close(self) -> None:
        try:
            self._token.undeclare()
            for q in self._queryables:
                q.undeclare()
            for p in self._pubs.values():
                p.undeclare()
        finally:
            self.session.close()
