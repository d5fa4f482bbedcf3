"""A fleet over a zenoh router, and the autopilot client.

Two emulated vehicles, each with its own daemon (two vehicle names), connect to one
zenoh router on loopback, as vehicles reach the shore over a radio link.  The fleet
watcher, connected only to the router, sees both, and notices when one stops.  The
client (navd.client) reads and commands one of them through the same router.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from navd.client import NavClient, NavFleet
from navd.hil.bench_vehicle import BenchVehicle, free_port
from navd.schema import Estimate


def _until(what: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if what():
            return True
        time.sleep(0.2)
    return what()


@pytest.fixture
def router() -> Iterator[str]:
    """A zenoh router (the same router zenohd runs), listening on loopback only."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"router"')
    cfg.insert_json5("listen/endpoints", f'["{endpoint}"]')
    cfg.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(cfg)
    try:
        yield endpoint
    finally:
        session.close()


def test_two_vehicles_one_router_one_fleet_watcher(router: str, tmp_path: Path) -> None:
    a = BenchVehicle(tmp_path / "a", subprocess.DEVNULL, vehicle="auv-a", connect=[router])
    b = BenchVehicle(tmp_path / "b", subprocess.DEVNULL, vehicle="auv-b", connect=[router])
    fleet = NavFleet([router])
    try:
        assert _until(lambda: {"auv-a", "auv-b"} <= set(fleet.latest), 60.0), fleet.latest
        assert _until(lambda: {"auv-a", "auv-b"} <= fleet.up, 10.0), fleet.up
        assert all(isinstance(e, Estimate) for e in fleet.latest.values())

        # the command-line watcher, through the router only
        out = subprocess.run(
            [sys.executable, "-m", "navd", "watch", "--fleet", "--seconds", "3"]
            + ["--connect", router],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert out.returncode == 0, out.stderr
        assert "auv-a" in out.stdout and "auv-b" in out.stdout

        # the client, through the router too
        with NavClient("auv-a", [router]) as nav:
            # a session just opened learns the router's routes within a moment
            assert _until(lambda: nav.alive, 10.0)
            latest: list[Estimate | None] = [None]

            def fetched() -> bool:
                latest[0] = nav.latest()
                return latest[0] is not None

            assert _until(fetched, 10.0)
            e = latest[0]
            assert e is not None and e.integrity in ("ok", "degraded", "lost")
            assert nav.set_beacon("spare", 37.05, -80.66, 2.0).ok
            refused = nav.set_beacon("spare", 91.0, 0.0)
            assert not refused.ok and "lat" in refused.error

            async def three() -> list[Estimate]:
                got: list[Estimate] = []
                async for x in nav.estimates():
                    got.append(x)
                    if len(got) == 3:
                        return got
                return got

            got = asyncio.run(asyncio.wait_for(three(), 10.0))
            assert [x.t for x in got] == sorted(x.t for x in got)

            answer = nav.reset()  # last: it restarts auv-a's filter
            assert answer.ok or "force" in answer.error  # refused only while submerged

        b.stop()  # one vehicle's daemon stops: its liveliness token goes
        assert _until(lambda: "auv-b" not in fleet.up, 15.0), fleet.up
        assert "auv-a" in fleet.up
        with NavClient("auv-b", [router], timeout_s=1.0) as gone:
            assert not gone.alive
    finally:
        fleet.close()
        for v in (a, b):
            v.stop()
            v.kill()


ROOT = Path(__file__).resolve().parent.parent


def test_the_shipped_fleet_configs_are_valid() -> None:
    """config/fleet: the vehicle overlay passes check-config on the vehicle's config, and
    the shore router's file opens as a zenoh router (here on a loopback port)."""
    from navd.config import load_config
    from navd.settings import check_for_run

    cfg = load_config(ROOT / "config" / "navd.yaml", [ROOT / "config" / "fleet" / "vehicle.yaml"])
    check_for_run(cfg)
    assert cfg.vehicle.name == "auv-1" and cfg.zenoh.connect == ["tcp/10.0.0.1:7447"]
    router = zenoh.Config.from_file(str(ROOT / "config" / "fleet" / "shore-router.json5"))
    router.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{free_port()}"]')
    zenoh.open(router).close()
