"""The client an autopilot uses fails safe: it never waits on a dead daemon, and never
hands over an old estimate as the vehicle's position.

Real zenoh sessions on loopback; the daemon's side is navd's own Publisher (in a
child process where it must die by SIGKILL).
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from test_commands import Loop

from navd.client import Gone, NavClient, NavUnavailable, NoAnswer, Stale
from navd.daemon.publish import Publisher, ResetCommand
from navd.hil.bench_vehicle import free_port
from navd.schema import Estimate, from_dict
from navd.settings import ZenohConfig

FIELDS = {"current_n": 0.0, "current_e": 0.0, "cov_ne": 0.0, "depth": 2.0, "mode": "submerged"}


def _estimate(t: float) -> Estimate:
    est = {"t": t, "lat": 37.05, "lon": -80.66, "std_n": 3.0, "std_e": 3.0, "integrity": "ok"}
    return from_dict(Estimate, est | FIELDS)


_CHILD = textwrap.dedent(
    """
    import asyncio, sys, time
    from navd.settings import ZenohConfig
    from navd.daemon.publish import Publisher
    from navd.schema import Estimate
    loop = asyncio.new_event_loop()
    pub = Publisher(ZenohConfig(listen=[sys.argv[1]]), "k9", loop, lambda n, b: None)
    t = 0.0
    print("up", flush=True)
    while True:
        pub.put(Estimate(t, 37.05, -80.66, 0.0, 0.0, 3.0, 3.0, 0.0, 2.0, "submerged", "ok"))
        t += 0.1
        time.sleep(0.1)
    """
)


def test_the_estimates_loop_ends_when_navd_is_killed() -> None:
    """After a kill -9 the loop of docs/zenoh.md raises within the staleness bound."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD, ep],
        stdout=subprocess.PIPE,
        text=True,
        cwd=Path(__file__).parent.parent,
    )
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == "up"
        with NavClient("k9", [ep], stale_s=1.0) as nav:

            async def run() -> tuple[int, float, BaseException]:
                n = 0
                t_kill = 0.0
                try:
                    async for _ in nav.estimates():
                        n += 1
                        if n == 10:
                            os.kill(child.pid, signal.SIGKILL)
                            t_kill = time.monotonic()
                except NavUnavailable as exc:
                    return n, time.monotonic() - t_kill, exc
                raise AssertionError("the loop ended without saying why")

            n, after, exc = asyncio.run(asyncio.wait_for(run(), 30.0))
        assert n >= 10
        assert isinstance(exc, Stale | Gone)
        assert after < 3.0  # not 10 s and counting: the bound (1 s) and zenoh's lease
    finally:
        child.kill()
        child.wait(10)


@pytest.fixture
def navd() -> tuple[Publisher, str, Loop]:
    ep = f"tcp/127.0.0.1:{free_port()}"
    loop = Loop()
    pub = Publisher(ZenohConfig(listen=[ep]), "t1", loop.loop, loop.on_command)
    yield pub, ep, loop
    pub.close()
    loop.close()


def test_the_estimates_loop_raises_stale_when_estimates_stop(navd) -> None:
    pub, ep, _ = navd
    with NavClient("t1", [ep], stale_s=0.5) as nav:

        async def run() -> BaseException:
            n = 0
            try:
                async for _ in nav.estimates():
                    n += 1
            except NavUnavailable as exc:
                return exc
            raise AssertionError

        async def publish() -> BaseException:
            task = asyncio.ensure_future(run())
            for k in range(10):
                pub.put(_estimate(k * 0.1))
                await asyncio.sleep(0.1)
            return await asyncio.wait_for(task, 5.0)  # navd alive, but silent

        exc = asyncio.run(publish())
    assert isinstance(exc, Stale) and "no estimate for 0.5 s" in str(exc)


def test_latest_is_never_old_nor_from_before_a_reset(navd) -> None:
    pub, ep, _ = navd
    with NavClient("t1", [ep], stale_s=1.0) as nav:
        pub.put(_estimate(1.0))
        e = nav.latest()
        assert e is not None and e.t == 1.0
        pub.forget_latest()  # what the daemon does on an accepted reset
        assert nav.latest() is None
        pub.put(_estimate(2.0))
        assert nav.latest() is not None
        time.sleep(1.3)  # navd stopped publishing: what it has is no position
        assert nav.latest() is None
        assert nav.latest(max_age_s=5.0) is None  # the daemon's own bound holds too
        nav.check()  # navd answered (with "no current estimate"): it is there


def test_an_accepted_reset_forgets_the_latest_estimate(tmp_path) -> None:
    from navd.daemon.daemon import Daemon
    from navd.settings import config_from_dict

    class Pub:
        forgotten = 0

        def forget_latest(self) -> None:
            self.forgotten += 1

    cfg = config_from_dict(
        {
            "log": {"dir": str(tmp_path)},
            "devices": {
                n: {"enabled": False} for n in ("ahrs", "gps", "pressure", "motor", "modem")
            },
        }
    )
    d = Daemon(cfg, clock=lambda: 100.0)
    d.pub = Pub()  # type: ignore[assignment]
    assert d.on_command(ResetCommand()) is None
    assert d.pub.forgotten == 1  # type: ignore[attr-defined]
    d.rlog.close()


def test_subscribe_reports_a_silence_once(navd) -> None:
    pub, ep, _ = navd
    said: list[NavUnavailable] = []
    with NavClient("t1", [ep], stale_s=0.4) as nav:
        nav.subscribe(lambda e: None, on_unavailable=said.append)
        for k in range(5):
            pub.put(_estimate(k * 0.1))
            time.sleep(0.1)
        time.sleep(1.2)
    assert len(said) == 1 and isinstance(said[0], Stale)


def test_wrong_credentials_and_silence_say_which(tmp_path) -> None:
    shipped = Path(__file__).parent.parent / "config" / "zenoh.json5"
    users = tmp_path / "zenoh-users.txt"
    users.write_text("autopilot:pilot-secret\nobserver:watch-secret\n")
    cfg_file = tmp_path / "zenoh.json5"
    cfg_file.write_text(shipped.read_text().replace("/etc/navd/zenoh-users.txt", str(users)))
    ep = f"tcp/127.0.0.1:{free_port()}"
    loop = Loop()
    pub = Publisher(
        ZenohConfig(listen=[ep], config_file=str(cfg_file)), "t1", loop.loop, loop.on_command
    )
    client_file = tmp_path / "client.json5"
    try:
        client_file.write_text(
            json.dumps({"transport": {"auth": {"usrpwd": {"user": "observer", "password": "x"}}}})
        )
        with pytest.raises(NavUnavailable, match="user 'observer'"):
            NavClient("t1", [ep], config_file=str(client_file))
        client_file.write_text(
            json.dumps(
                {
                    "transport": {
                        "auth": {"usrpwd": {"user": "observer", "password": "watch-secret"}}
                    }
                }
            )
        )
        nobody = NavClient("no-such-vehicle", [ep], config_file=str(client_file), timeout_s=1.0)
        try:
            with pytest.raises(
                NoAnswer,
                match=f"no answer from auv/no-such-vehicle/nav via {re.escape(ep)} within 1 s: "
                "is navd up, and may user 'observer' read it",
            ):
                nobody.check()
        finally:
            nobody.close()
        with NavClient("t1", [ep], config_file=str(client_file)) as nav:
            pub.put(_estimate(1.0))
            assert nav.latest() is not None  # the right credentials read navd
    finally:
        pub.close()
        loop.close()


def test_navd_watch_takes_a_zenoh_file_under_the_shipped_access_control(tmp_path) -> None:
    """README step 5 secures zenoh; step 6 (navd watch) then needs its credentials."""
    shipped = Path(__file__).parent.parent / "config"
    users = tmp_path / "zenoh-users.txt"
    users.write_text("observer:watch-secret\n")
    vehicle_file = tmp_path / "zenoh.json5"
    text = (shipped / "zenoh.json5").read_text()
    vehicle_file.write_text(text.replace("/etc/navd/zenoh-users.txt", str(users)))
    client_file = tmp_path / "client.json5"
    client_file.write_text(
        (shipped / "zenoh-client.json5").read_text().replace("set-on-the-vehicle", "watch-secret")
    )
    ep = f"tcp/127.0.0.1:{free_port()}"
    cfg = tmp_path / "navd.yaml"
    cfg.write_text(f"vehicle: {{name: t1}}\nzenoh: {{listen: ['{ep}']}}\n")
    loop = Loop()
    pub = Publisher(
        ZenohConfig(listen=[ep], config_file=str(vehicle_file)), "t1", loop.loop, loop.on_command
    )
    stop = [False]

    def publish() -> None:
        k = 0
        while not stop[0]:
            pub.put(_estimate(k * 0.1))
            k += 1
            time.sleep(0.1)

    import threading

    th = threading.Thread(target=publish, daemon=True)
    th.start()
    try:
        base = [sys.executable, "-m", "navd", "watch", "--config", str(cfg), "--count", "3"]
        ok = subprocess.run(
            [*base, "--zenoh-config", str(client_file), "--every", "0"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert ok.returncode == 0, ok.stderr
        assert len(ok.stdout.strip().splitlines()) == 3
        refused = subprocess.run(
            [*base, "--seconds", "3"], capture_output=True, text=True, timeout=60
        )
        assert refused.returncode == 1
        assert "cannot open a zenoh session" in refused.stderr and "Traceback" not in refused.stderr
        missing = subprocess.run(
            [*base, "--zenoh-config", str(tmp_path / "nope.json5")],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert missing.returncode == 2 and "nope.json5: cannot open" in missing.stderr
    finally:
        stop[0] = True
        th.join(5)
        pub.close()
        loop.close()


def test_navd_foxglove_reads_its_zenoh_file_as_the_others_do(tmp_path) -> None:
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "navd",
            "foxglove",
            "--zenoh-config",
            str(tmp_path / "nope.json5"),
            "--seconds",
            "1",
            "--port",
            str(free_port()),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "--zenoh-config" in r.stderr and "nope.json5" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_navd_watch_with_no_navd_behind_the_endpoint_says_so(tmp_path) -> None:
    """A zenoh session answers on the endpoint but no navd does: watch --count 1 does not
    wait forever; it says which vehicle it asked, and where."""
    import zenoh

    ep = f"tcp/127.0.0.1:{free_port()}"
    conf = zenoh.Config.from_json5(json.dumps({"mode": "peer", "listen": {"endpoints": [ep]}}))
    other = zenoh.open(conf)
    try:
        cfg = tmp_path / "navd.yaml"
        cfg.write_text(f"vehicle: {{name: nobody}}\nzenoh: {{connect: ['{ep}']}}\n")
        t0 = time.monotonic()
        r = subprocess.run(
            [sys.executable, "-m", "navd", "watch", "--config", str(cfg), "--count", "1"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert r.returncode == 1 and time.monotonic() - t0 < 40
        assert "auv/nobody/nav" in r.stderr and ep in r.stderr and "Traceback" not in r.stderr
    finally:
        other.close()
