"""``navd foxglove``: the fleet, live, in Foxglove.

A shore-side bridge: it subscribes to ``auv/*/nav/**`` over zenoh and serves
Foxglove's WebSocket protocol with the Foxglove SDK's own server, so an operator
opens Foxglove (``ws://127.0.0.1:8765``) and sees every vehicle on the Map panel as
it navigates.  Per vehicle: ``/<vehicle>/estimate`` (``foxglove.LocationFix`` with
its covariance), ``/<vehicle>/range`` and ``/<vehicle>/health`` (JSON).  It binds to
127.0.0.1 unless told otherwise: the operator's own machine, not the ship's network.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from navd.client import open_session
from navd.formats import jsonlines
from navd.formats.foxglove_mcap import location_fix
from navd.zenohconf import read_zenoh_file

DEFAULT_PORT = 8765


class Bridge:
    def __init__(
        self,
        connect: list[str],
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        zenoh_file: str | None = None,
    ):
        import foxglove

        # the zenoh file first: a bad one is a one-line error before anything is served
        zcfg = read_zenoh_file(zenoh_file, "--zenoh-config") if zenoh_file else None
        self._fg = foxglove
        self.ctx = foxglove.Context()
        self.server = foxglove.start_server(name="navd", host=host, port=port, context=self.ctx)
        self.session = open_session(connect, zcfg)
        self._lock = threading.Lock()
        self._channels: dict[str, Any] = {}
        self.messages = 0
        self._sub = self.session.declare_subscriber("auv/*/nav/**", self._on_sample)

    @property
    def port(self) -> int:
        return int(self.server.port)

    def _channel(self, topic: str, kind: str) -> Any:
        with self._lock:
            ch = self._channels.get(topic)
            if ch is None:
                if kind == "estimate":
                    from foxglove.channels import LocationFixChannel

                    ch = LocationFixChannel(topic, context=self.ctx)
                else:
                    schema = {"type": "object", "title": topic, "additionalProperties": True}
                    ch = self._fg.Channel(
                        topic, schema=schema, message_encoding="json", context=self.ctx
                    )
                self._channels[topic] = ch
            return ch

    def _on_sample(self, sample: Any) -> None:
        parts = str(sample.key_expr).split("/")  # auv/<vehicle>/nav/<kind>
        if len(parts) != 4 or parts[3] not in ("estimate", "range", "health"):
            return
        vehicle, kind = parts[1], parts[3]
        try:
            body = jsonlines.loads(sample.payload.to_bytes())
        except jsonlines.DecodeError:
            return
        if not isinstance(body, dict):
            return
        topic = f"/{vehicle}/{kind}"
        now_ns = time.time_ns()
        try:
            if kind == "estimate":
                msg = location_fix(body["lat"], body["lon"], body["depth"], body, now_ns)
                self._channel(topic, kind).log(msg, log_time=now_ns)
            else:
                self._channel(topic, kind).log(body, log_time=now_ns)
        except (KeyError, TypeError, ValueError):
            return  # not navd's schema: another publisher under auv/*
        self.messages += 1

    def close(self) -> None:
        try:
            self._sub.undeclare()
            self.session.close()
        finally:
            self.server.stop()


def serve(
    connect: list[str],
    host: str,
    port: int,
    seconds: float | None = None,
    zenoh_file: str | None = None,
) -> int:
    bridge = Bridge(connect, host, port, zenoh_file)
    print(f"navd foxglove: ws://{host}:{bridge.port} (open it in Foxglove)", flush=True)
    t_end = time.monotonic() + seconds if seconds else None
    try:
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        bridge.close()
    return 0
