"""``navd foxglove``: the fleet, live, in Foxglove.

A shore-side bridge: it subscribes to ``auv/*/nav/**`` over zenoh and serves
Foxglove's WebSocket protocol with the Foxglove SDK's own server, so an operator
opens Foxglove (``ws://127.0.0.1:8765``) and sees every vehicle on the Map panel as
it navigates.  Per vehicle: ``/<vehicle>/estimate`` (``foxglove.LocationFix`` with
its covariance), ``/<vehicle>/range``, ``/<vehicle>/health`` and ``/<vehicle>/advisory``
(JSON, with their fields' schema from navd/schema.py, for plots).  A vehicle silent for
``SILENT_S`` gets a ``/<vehicle>/log`` warning and a line on stderr, once, so a
frozen marker on the map is not mistaken for a live one.  It binds to 127.0.0.1
unless told otherwise: the operator's own machine, not the ship's network.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar, cast

from navd.client import open_session
from navd.formats import jsonlines
from navd.formats.foxglove_mcap import location_fix
from navd.formats.jsonschema import schema_of
from navd.schema import Advisory, Estimate, Health, RangeDecision, output_of
from navd.zenohconf import read_zenoh_file

if TYPE_CHECKING:  # the SDK is an extra, imported when the bridge starts
    import foxglove
    import zenoh
    from foxglove.channels import LocationFixChannel, LogChannel

C = TypeVar("C")

DEFAULT_PORT = 8765
#: what the SDK's server accepts (foxglove-sdk's websocket handshake); not configurable
SUBPROTOCOL = "foxglove.sdk.v1"
#: a vehicle that published nothing for this long is said to be silent (health is 1 Hz)
SILENT_S = 5.0
_JSON_KINDS: dict[str, type] = {"range": RangeDecision, "health": Health, "advisory": Advisory}


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
        self.ctx = foxglove.Context()
        self.server = foxglove.start_server(name="navd", host=host, port=port, context=self.ctx)
        self.session = open_session(connect, zcfg)
        self._lock = threading.Lock()
        self._channels: dict[str, object] = {}
        self.messages = 0
        self._heard: dict[str, float] = {}  # vehicle: monotonic time of its last message
        self._silent: set[str] = set()
        self._sub = self.session.declare_subscriber("auv/*/nav/**", self._on_sample)

    @property
    def port(self) -> int:
        return int(self.server.port)

    def _channel(self, topic: str, make: Callable[[], C]) -> C:
        """The topic's channel, made on first use (samples come on zenoh's threads)."""
        with self._lock:
            ch = self._channels.get(topic)
            if ch is None:
                ch = self._channels[topic] = make()
            return cast(C, ch)  # one topic, one kind of channel: the topic names its kind

    def _fix_channel(self, topic: str) -> LocationFixChannel:
        from foxglove.channels import LocationFixChannel

        return self._channel(topic, lambda: LocationFixChannel(topic, context=self.ctx))

    def _log_channel(self, topic: str) -> LogChannel:
        from foxglove.channels import LogChannel

        return self._channel(topic, lambda: LogChannel(topic, context=self.ctx))

    def _json_channel(self, topic: str, kind: str) -> foxglove.Channel:
        import foxglove

        schema = schema_of(_JSON_KINDS[kind], title=topic)
        return self._channel(
            topic,
            lambda: foxglove.Channel(
                topic, schema=schema, message_encoding="json", context=self.ctx
            ),
        )

    def _on_sample(self, sample: zenoh.Sample) -> None:
        parts = str(sample.key_expr).split("/")  # auv/<vehicle>/nav/<kind>
        if len(parts) != 4 or parts[3] not in ("estimate", *_JSON_KINDS):
            return
        vehicle, kind = parts[1], parts[3]
        try:
            body = jsonlines.object_or_none(jsonlines.loads(sample.payload.to_bytes()))
        except jsonlines.DecodeError:
            return
        if body is None:
            return
        topic = f"/{vehicle}/{kind}"
        now_ns = time.time_ns()
        try:
            if kind == "estimate":
                est = output_of(body)
                if not isinstance(est, Estimate):
                    return  # not navd's schema: another publisher under auv/*
                msg = location_fix(est.lat, est.lon, est.depth, est, now_ns)
                self._fix_channel(topic).log(msg, log_time=now_ns)
            else:
                self._json_channel(topic, kind).log(body, log_time=now_ns)
        except (KeyError, TypeError, ValueError):
            return  # not navd's schema: another publisher under auv/*
        self.messages += 1
        with self._lock:
            self._heard[vehicle] = time.monotonic()
            came_back = vehicle in self._silent
            self._silent.discard(vehicle)
        if came_back:
            self._say(vehicle, "info", f"{vehicle} is publishing again")

    def check_silence(self, now: float | None = None) -> list[str]:
        """Vehicles that fell silent since the last check; each is said once."""
        now = time.monotonic() if now is None else now
        with self._lock:
            gone = [
                v for v, t in self._heard.items() if now - t > SILENT_S and v not in self._silent
            ]
            self._silent.update(gone)
        for v in gone:
            self._say(
                v, "warning", f"{v} silent for {SILENT_S:.0f} s: its last estimate is not live"
            )
        return gone

    def _say(self, vehicle: str, level: str, text: str) -> None:
        from foxglove.messages import Log, LogLevel, Timestamp

        print(f"navd foxglove: {text}", file=sys.stderr, flush=True)
        t_ns = time.time_ns()
        stamp = Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)
        lv = LogLevel.Warning if level == "warning" else LogLevel.Info
        msg = Log(timestamp=stamp, level=lv, message=text, name="navd foxglove")
        self._log_channel(f"/{vehicle}/log").log(msg, log_time=t_ns)

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
    print(
        f"navd foxglove: ws://{host}:{bridge.port} (open it in Foxglove; WebSocket "
        f"subprotocol {SUBPROTOCOL} only, docs/tools.md lists the viewers that speak it)",
        flush=True,
    )
    t_end = time.monotonic() + seconds if seconds else None
    try:
        while t_end is None or time.monotonic() < t_end:
            time.sleep(0.5)
            bridge.check_silence()
    except KeyboardInterrupt:
        pass
    finally:
        bridge.close()
    return 0
