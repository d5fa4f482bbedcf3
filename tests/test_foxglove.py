"""navd foxglove: a daemon on the emulated vehicle, the bridge, and a WebSocket client on
loopback that subscribes the way Foxglove does and receives the vehicle's estimate."""

from __future__ import annotations

import asyncio
import json
import struct
import subprocess
import time
from pathlib import Path

import websockets

from navd.foxglove_bridge import SILENT_S, Bridge
from navd.hil.bench_vehicle import BenchVehicle

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


_RESUBSCRIBE_S = 3.0  # every topic here publishes at least once a second


async def _subscribe(
    ws: websockets.ClientConnection, subs: dict[int, str], channel: int, topic: str
) -> None:
    sid = len(subs) + 1
    subs[sid] = topic
    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": sid, "channelId": channel}]}))  # fmt: skip


async def _receive(
    port: int, topics: list[str], timeout: float, schemas: dict[str, str] | None = None
) -> dict[str, bytes]:
    """Subscribe to ``topics`` once advertised; the first message of each (and, into
    ``schemas``, the schema each was advertised with)."""
    got: dict[str, bytes] = {}
    subs: dict[int, str] = {}
    channels: dict[int, str] = {}  # advertised, by channel id
    async with websockets.connect(
        f"ws://127.0.0.1:{port}",
        subprotocols=SUBPROTOCOLS,  # type: ignore[arg-type]
    ) as ws:
        async with asyncio.timeout(timeout):
            again = time.monotonic() + _RESUBSCRIBE_S
            while len(got) < len(topics):
                frame = await ws.recv()
                if time.monotonic() > again:
                    # The SDK's server can advertise a new channel a moment before it
                    # takes subscriptions to it: on a loaded machine the subscribe comes
                    # back "unknown channel" and nothing follows.  Subscribe again to what
                    # was advertised and has sent nothing, as a viewer reopening a panel.
                    again = time.monotonic() + _RESUBSCRIBE_S
                    for cid, topic in channels.items():
                        if topic not in got:
                            await _subscribe(ws, subs, cid, topic)
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg.get("op") != "advertise":
                        continue
                    want = [c for c in msg["channels"] if c["topic"] in topics]
                    for c in want:
                        if schemas is not None:
                            schemas[c["topic"]] = c.get("schema", "")
                        channels[c["id"]] = c["topic"]
                        await _subscribe(ws, subs, c["id"], c["topic"])
                elif frame[0] == 0x01:  # MessageData: op, subscription, log time, payload
                    (sid,) = struct.unpack_from("<I", frame, 1)
                    topic = subs.get(sid)
                    if topic is not None:
                        got.setdefault(topic, bytes(frame[13:]))
    return got


def test_an_operator_sees_the_vehicle_live(tmp_path: Path) -> None:
    v = BenchVehicle(tmp_path / "v", subprocess.DEVNULL)
    bridge = Bridge([f"tcp/127.0.0.1:{v.port}"], port=0)
    try:
        schemas: dict[str, str] = {}
        topics = ["/sim690s/estimate", "/sim690s/health", "/sim690s/advisory"]
        got = asyncio.run(_receive(bridge.port, topics, timeout=60.0, schemas=schemas))
        assert len(got["/sim690s/estimate"]) > 20  # a LocationFix, encoded by the SDK
        health = json.loads(got["/sim690s/health"])
        assert health["type"] == "health" and "devices" in health
        assert json.loads(got["/sim690s/advisory"])["type"] == "advisory"
        # JSON channels say their fields, so Foxglove offers them for plots
        props = json.loads(schemas["/sim690s/health"])["properties"]
        assert props["ok"] == {"type": "boolean"} and "devices" in props
        assert bridge.messages > 0
        # the vehicle stops: the bridge says so once, instead of showing its last fix as live
        assert bridge.check_silence() == []
        v.stop()
        v.kill()
        time.sleep(SILENT_S + 1.5)
        assert bridge.check_silence() == ["sim690s"]
        assert bridge.check_silence() == []
    finally:
        bridge.close()
        v.stop()
        v.kill()
