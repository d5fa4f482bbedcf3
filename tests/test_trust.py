"""Who may speak as navd: the shipped access control (config/zenoh.json5) on loopback.

What an autopilot relies on: every estimate, range, health, ``latest`` answer and
liveliness token it sees under ``auv/<v>/nav`` is navd's.  A crew member's session
(here an ``observer``, with valid credentials) tries each forgery once seen to get
through; none reaches the autopilot's :class:`NavClient`, and navd's own messages
still do.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh
from test_commands import Loop

from navd.client import NavClient, NavFleet
from navd.daemon.publish import Publisher
from navd.hil.bench_vehicle import free_port
from navd.schema import Estimate, Health, from_dict
from navd.settings import ZenohConfig

SHIPPED = Path(__file__).parent.parent / "config" / "zenoh.json5"
_FIELDS = {"current_n": 0.0, "current_e": 0.0, "cov_ne": 0.0, "depth": 2.0, "mode": "submerged"}
FORGED = {
    "t": 1.0,
    "lat": 0.0,
    "lon": 0.0,
    "std_n": 0.1,
    "std_e": 0.1,
    "integrity": "ok",
    **_FIELDS,
}


def _client_config(port: int, user: str, password: str) -> zenoh.Config:
    c = zenoh.Config()
    c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    c.insert_json5("transport/auth/usrpwd", json.dumps({"user": user, "password": password}))
    return c


def _hostile(port: int) -> zenoh.Session:
    """An observer who configures its own session as it likes: a peer, listening."""
    c = _client_config(port, "observer", "watch-secret")
    c.insert_json5("mode", '"peer"')
    c.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{free_port()}"]))
    c.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(c)


@pytest.fixture
def vehicle(tmp_path: Path) -> Iterator[tuple[Publisher, int, Loop]]:
    users = tmp_path / "zenoh-users.txt"
    users.write_text("autopilot:pilot-secret\nobserver:watch-secret\n")
    cfg_file = tmp_path / "zenoh.json5"
    cfg_file.write_text(SHIPPED.read_text().replace("/etc/navd/zenoh-users.txt", str(users)))
    port = free_port()
    loop = Loop()
    pub = Publisher(
        ZenohConfig(listen=[f"tcp/127.0.0.1:{port}"], config_file=str(cfg_file)),
        "t1",
        loop.loop,
        loop.on_command,
    )
    try:
        yield pub, port, loop
    finally:
        pub.close()
        loop.close()


def _estimate(t: float) -> Estimate:
    est = {"t": t, "lat": 37.05, "lon": -80.66, "std_n": 3.0, "std_e": 3.0, "integrity": "ok"}
    return from_dict(Estimate, {**est, **_FIELDS})


def _health(t: float) -> Health:
    return Health(
        t, "submerged", "ok", True, [], 10.0, {}, None, {}, {}, {}, {}, 0, 0, {}, {}, {}, {},
        None, None, {},
    )  # fmt: skip


def _publish_for(pub: Publisher, seconds: float, stop: threading.Event) -> None:
    t = 100.0
    end = time.monotonic() + seconds
    while time.monotonic() < end and not stop.is_set():
        pub.put(_estimate(t))
        pub.put(_health(t))
        t += 0.1
        time.sleep(0.1)


def test_no_crew_session_can_speak_as_navd(vehicle) -> None:
    pub, port, _ = vehicle
    hostile = _hostile(port)
    pilot = NavClient("t1", config=_client_config(port, "autopilot", "pilot-secret"))
    seen: list[Any] = []
    ranges: list[Any] = []
    pilot.subscribe(seen.append, ranges.append)
    health: list[bytes] = []
    sub = pilot.session.declare_subscriber(
        "auv/t1/nav/health", lambda s: health.append(s.payload.to_bytes())
    )
    ghost_token = hostile.liveliness().declare_token("auv/ghost/nav/alive")
    forged_latest = hostile.declare_queryable(
        "auv/t1/nav/latest",
        lambda q: q.reply("auv/t1/nav/latest", json.dumps({"schema": 1, **FORGED})),
    )
    stop = threading.Event()
    navd = threading.Thread(target=_publish_for, args=(pub, 4.0, stop), daemon=True)
    navd.start()
    try:
        time.sleep(0.5)
        for _ in range(20):
            hostile.put("auv/t1/nav/estimate", json.dumps({"schema": 1, **FORGED}))
            hostile.put("auv/t1/nav/health", json.dumps({"schema": 1, "t": 1.0, "status": "ok"}))
            hostile.put(
                "auv/t1/nav/range",
                json.dumps(
                    {"schema": 1, "t": 1.0, "t_ping": 0.5, "beacon": "udb", "accepted": True}
                ),
            )
            time.sleep(0.05)
        answers = [pilot.latest() for _ in range(5)]
        fleet = NavFleet(config=_client_config(port, "autopilot", "pilot-secret"))
        time.sleep(1.0)
        up = set(fleet.up)
        fleet.close()
    finally:
        stop.set()
        navd.join()
        sub.undeclare()
        forged_latest.undeclare()
        ghost_token.undeclare()
        hostile.close()
        pilot.close()
    assert seen, "navd's own estimates must still arrive"
    assert all(e.lat == pytest.approx(37.05) for e in seen), "a forged estimate got through"
    assert ranges == []  # navd published no range: every one seen would be forged
    assert health and all(b'"type":"health"' in h and b'"t":1.0' not in h for h in health)
    assert all(a is not None and a.lat == pytest.approx(37.05) for a in answers)
    assert up == {"t1"}  # navd's token, and no ghost


def test_a_crew_subscription_is_not_routed_to_another_crew_member(vehicle) -> None:
    """Two crew sessions connected only through navd: one's put never reaches the other."""
    _, port, _ = vehicle
    a = NavClient("t1", config=_client_config(port, "observer", "watch-secret"))
    b = _hostile(port)
    got: list[Any] = []
    subs = [
        a.session.declare_subscriber(f"auv/t1/nav/{k}", got.append)
        for k in ("estimate", "health", "range", "advisory")
    ]
    try:
        time.sleep(0.5)
        for k in ("estimate", "health", "range", "advisory"):
            b.put(f"auv/t1/nav/{k}", b"{}")
        time.sleep(0.5)
    finally:
        for sub in subs:
            sub.undeclare()
        b.close()
        a.close()
    assert got == []
