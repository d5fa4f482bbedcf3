"""Commands over a real zenoh session on loopback: every one answered, none unbounded.

Each case here once went unanswered (the exception stayed in zenoh's thread),
grew the daemon's memory without bound, or stopped navigation.
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
from collections.abc import Iterator
from dataclasses import replace

import pytest
import zenoh

from navd.daemon.publish import (
    COMMAND_BURST,
    MAX_COMMAND_BYTES,
    BeaconCommand,
    Command,
    Publisher,
    ResetCommand,
    TokenBucket,
    parse_command,
    validate_beacon,
    validate_reset,
    zenoh_config,
)
from navd.schema import Estimate
from navd.settings import ZenohConfig


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Loop:
    """The daemon's event loop, in a thread, answering commands as the daemon would."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.seen: list[Command] = []
        self.submerged = False
        self.endpoints: list[str] = []

    def on_command(self, cmd: Command) -> str | None:
        if isinstance(cmd, ResetCommand) and self.submerged and not cmd.force:
            return "submerged: send force"
        self.seen.append(cmd)
        return None

    def close(self) -> None:
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)


@pytest.fixture
def vehicle() -> Iterator[tuple[Loop, Publisher, zenoh.Session]]:
    port = _free_port()
    zc = ZenohConfig(listen=[f"tcp/127.0.0.1:{port}"])
    loop = Loop()
    loop.endpoints = list(zc.listen)
    pub = Publisher(zc, "t1", loop.loop, loop.on_command)
    client = zenoh.open(zenoh_config(replace(zc, listen=[], connect=list(zc.listen))))
    try:
        yield loop, pub, client
    finally:
        client.close()
        pub.close()
        loop.close()


def _ask(session: zenoh.Session, cmd: str, payload: bytes) -> list[dict]:
    replies = session.get(f"auv/t1/nav/cmd/{cmd}", payload=payload, timeout=5.0)
    return [json.loads(r.ok.payload.to_bytes()) for r in replies if r.ok is not None]


@pytest.mark.parametrize(
    "payload",
    [
        b'{"name":"x","lat":' + b"9" * 400 + b',"lon":1}',
        b"[" * 100_000 + b"]" * 100_000,
        b'{"name":"' + b"x" * (16 * 1024 * 1024) + b'","lat":1,"lon":1}',
        b'{"name":"a\\u0000b","lat":1,"lon":1}',
        b"\xff\xfe",
        b'{"name":"x","lat":1,"lon":1,"depth":-1}',
    ],
    ids=["400-digits", "deep-nesting", "16MB-name", "control-char", "not-utf8", "depth"],
)
def test_every_malformed_command_is_answered_and_changes_nothing(
    vehicle: tuple[Loop, Publisher, zenoh.Session], payload: bytes
) -> None:
    loop, pub, client = vehicle
    (reply,) = _ask(client, "beacon", payload)
    assert reply["ok"] is False and reply["error"]
    assert loop.seen == []


def test_a_reset_while_submerged_needs_force(vehicle: tuple[Loop, Publisher, zenoh.Session]):
    loop, pub, client = vehicle
    loop.submerged = True
    (reply,) = _ask(client, "reset", b"{}")
    assert reply["ok"] is False and "force" in reply["error"]
    (reply,) = _ask(client, "reset", b'{"force": true, "reason": "operator"}')
    assert reply == {"ok": True}
    assert loop.seen == [ResetCommand(reason="operator", force=True)]


def test_command_spam_is_rate_limited(vehicle: tuple[Loop, Publisher, zenoh.Session]) -> None:
    loop, pub, client = vehicle
    replies = [_ask(client, "reset", b"{}")[0] for _ in range(50)]
    ok = [r for r in replies if r["ok"]]
    # the burst, and what the bucket refilled while the 50 queries ran
    assert COMMAND_BURST <= len(ok) < 20
    assert pub.commands["rate_limited"] == 50 - len(ok)
    assert all("rate limited" in r["error"] for r in replies if not r["ok"])


def test_parse_command_is_total_and_bounded() -> None:
    assert parse_command(b"x" * (MAX_COMMAND_BYTES + 1), validate_beacon) == (
        f"payload longer than {MAX_COMMAND_BYTES} bytes"
    )
    assert parse_command(b"{}", validate_reset) == ResetCommand()
    assert isinstance(parse_command(b'{"force": 1}', validate_reset), str)
    assert isinstance(
        parse_command(b'{"name": "' + b"n" * 33 + b'", "lat": 0, "lon": 0}', validate_beacon), str
    )
    assert parse_command(b'{"name": "udb-2", "lat": 0, "lon": 0}', validate_beacon) == (
        BeaconCommand(name="udb-2", lat=0.0, lon=0.0)
    )
    assert parse_command(b'{"name": "udb-2", "lat": 0}', validate_beacon) == "lon: missing"


def test_token_bucket_refills_at_its_rate() -> None:
    t = [0.0]
    b = TokenBucket(2.0, 3, clock=lambda: t[0])
    assert [b.take() for _ in range(4)] == [True, True, True, False]
    t[0] = 0.5
    assert [b.take(), b.take()] == [True, False]


def test_the_shipped_access_control_refuses_commands_of_the_unauthorised(tmp_path) -> None:
    """config/zenoh.json5 on loopback: credentials made here, never committed."""
    from pathlib import Path

    shipped = Path(__file__).parent.parent / "config" / "zenoh.json5"
    users = tmp_path / "zenoh-users.txt"
    users.write_text("autopilot:pilot-secret\nobserver:watch-secret\n")
    text = shipped.read_text()
    assert "/etc/navd/zenoh-users.txt" in text
    cfg_file = tmp_path / "zenoh.json5"
    cfg_file.write_text(text.replace("/etc/navd/zenoh-users.txt", str(users)))
    port = _free_port()
    zc = ZenohConfig(listen=[f"tcp/127.0.0.1:{port}"], config_file=str(cfg_file))
    loop = Loop()
    pub = Publisher(zc, "t1", loop.loop, loop.on_command)

    def session(user: str | None, password: str = "") -> zenoh.Session:
        c = zenoh.Config()
        c.insert_json5("mode", '"client"')
        c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
        c.insert_json5("scouting/multicast/enabled", "false")
        if user:
            c.insert_json5(
                "transport/auth/usrpwd", json.dumps({"user": user, "password": password})
            )
        return zenoh.open(c)

    try:
        observer = session("observer", "watch-secret")
        pub.put(Estimate(1.0, 37.05, -80.66, 0.0, 0.0, 3.0, 3.0, 0.0, 2.0, "submerged", "ok"))
        latest = [r for r in observer.get("auv/t1/nav/latest", timeout=3.0) if r.ok is not None]
        assert len(latest) == 1  # telemetry is the crew's
        assert _ask(observer, "reset", b"{}") == []  # its command never reaches navd
        assert loop.seen == []
        observer.close()
        for user, password in ((None, ""), ("observer", "guess")):
            with pytest.raises(zenoh.ZError):
                session(user, password)  # not even a session without the credentials
        pilot = session("autopilot", "pilot-secret")
        assert _ask(pilot, "reset", b"{}") == [{"ok": True}]
        assert loop.seen == [ResetCommand()]
        pilot.close()
    finally:
        pub.close()
        loop.close()


def _openssl(*args: str, cwd) -> None:
    import subprocess

    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def _certificates(d) -> None:
    """A CA, the vehicle's and the shore's certificates, and a stranger's from another CA."""
    for ca in ("ca", "other-ca"):
        _openssl(
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:P-256",
            "-nodes",
            "-days",
            "1",
            "-subj",
            f"/CN={ca}",
            "-keyout",
            f"{ca}.key",
            "-out",
            f"{ca}.pem",
            cwd=d,
        )
    (d / "san.ext").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    for who, ca in (("vehicle", "ca"), ("shore", "ca"), ("stranger", "other-ca")):
        _openssl(
            "req",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:P-256",
            "-nodes",
            "-subj",
            f"/CN={who}",
            "-keyout",
            f"{who}.key",
            "-out",
            f"{who}.csr",
            cwd=d,
        )
        _openssl(
            "x509",
            "-req",
            "-in",
            f"{who}.csr",
            "-CA",
            f"{ca}.pem",
            "-CAkey",
            f"{ca}.key",
            "-CAcreateserial",
            "-days",
            "1",
            "-extfile",
            "san.ext",
            "-out",
            f"{who}.pem",
            cwd=d,
        )


def test_a_shore_link_over_tls_with_mutual_authentication(tmp_path) -> None:
    """The shore link of docs/zenoh.md: only a certificate of the vehicle's CA gets in."""
    import shutil

    if shutil.which("openssl") is None:
        pytest.skip("openssl is needed to make the test certificates")
    _certificates(tmp_path)
    port = _free_port()

    def tls(key: str | None, ca: str = "ca") -> str:
        t = {"root_ca_certificate": str(tmp_path / f"{ca}.pem"), "enable_mtls": True}
        if key:
            t["connect_private_key"] = str(tmp_path / f"{key}.key")
            t["connect_certificate"] = str(tmp_path / f"{key}.pem")
        return json.dumps(t)

    vehicle_cfg = tmp_path / "vehicle.json5"
    vehicle_cfg.write_text(
        json.dumps(
            {
                "transport": {
                    "link": {
                        "tls": {
                            "root_ca_certificate": str(tmp_path / "ca.pem"),
                            "listen_private_key": str(tmp_path / "vehicle.key"),
                            "listen_certificate": str(tmp_path / "vehicle.pem"),
                            "enable_mtls": True,
                        }
                    }
                }
            }
        )
    )
    zc = ZenohConfig(listen=[f"tls/localhost:{port}"], config_file=str(vehicle_cfg))
    loop = Loop()
    pub = Publisher(zc, "t1", loop.loop, loop.on_command)

    def session(key: str | None) -> zenoh.Session:
        c = zenoh.Config()
        c.insert_json5("mode", '"client"')
        c.insert_json5("connect/endpoints", json.dumps([f"tls/localhost:{port}"]))
        c.insert_json5("scouting/multicast/enabled", "false")
        c.insert_json5("transport/link/tls", tls(key))
        return zenoh.open(c)

    try:
        shore = session("shore")
        assert _ask(shore, "reset", b"{}") == [{"ok": True}]
        shore.close()
        for key in (None, "stranger"):
            with pytest.raises(zenoh.ZError):
                session(key)
        assert loop.seen == [ResetCommand()]
    finally:
        pub.close()
        loop.close()


def test_a_flood_of_malformed_commands_costs_a_valid_one_nothing(
    vehicle: tuple[Loop, Publisher, zenoh.Session],
) -> None:
    """Another session floods malformed commands; the autopilot's are all accepted."""
    loop, pub, client = vehicle
    flooder = zenoh.open(zenoh_config(ZenohConfig(listen=[], connect=loop.endpoints)))
    stop = threading.Event()

    def flood() -> None:
        while not stop.is_set():
            flooder.get("auv/t1/nav/cmd/beacon", payload=b'{"name":', timeout=1.0)

    threads = [threading.Thread(target=flood, daemon=True) for _ in range(3)]
    for th in threads:
        th.start()
    try:
        answers = [
            _ask(
                client, "beacon", json.dumps({"name": f"b{k}", "lat": 37.0, "lon": -80.0}).encode()
            )
            for k in range(COMMAND_BURST)
        ]
    finally:
        stop.set()
        for th in threads:
            th.join(5)
        flooder.close()
    assert answers == [[{"ok": True}]] * COMMAND_BURST
    assert pub.commands["rejected"] > 20 and pub.commands["rate_limited"] == 0


def test_a_key_given_twice_is_refused(vehicle: tuple[Loop, Publisher, zenoh.Session]) -> None:
    loop, pub, client = vehicle
    loop.submerged = True
    (reply,) = _ask(client, "reset", b'{"force": false, "force": true}')
    assert reply["ok"] is False and "'force' given twice" in reply["error"]
    assert loop.seen == []
    assert isinstance(parse_command(b'{"lat": NaN, "name": "a", "lon": 0}', validate_beacon), str)


def test_resets_are_spaced_so_that_they_cannot_stop_navigation(tmp_path) -> None:
    """Any reset at most once per 10 s, a forced one at most once a minute."""
    from navd.daemon.daemon import Daemon
    from navd.settings import config_from_dict

    now = [100.0]
    cfg = config_from_dict(
        {
            "log": {"dir": str(tmp_path)},
            "devices": {
                n: {"enabled": False} for n in ("ahrs", "gps", "pressure", "motor", "modem")
            },
        }
    )
    d = Daemon(cfg, clock=lambda: now[0])
    assert d.on_command(ResetCommand()) is None
    now[0] += 5.0
    assert "at most one every 10 s" in (d.on_command(ResetCommand()) or "")
    now[0] += 6.0
    assert d.on_command(ResetCommand(force=True)) is None
    now[0] += 11.0
    assert "once every 60 s" in (d.on_command(ResetCommand(force=True)) or "")
    assert d.on_command(ResetCommand()) is None  # an unforced one, 11 s later, is fine
    now[0] += 50.0
    assert d.on_command(ResetCommand(force=True)) is None
    d.rlog.close()
