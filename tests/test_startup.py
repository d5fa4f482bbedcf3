"""Start-up and resources: bad configs get one line, zenoh trouble never stops navigation,
and the log stays within its budgets."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from navd.config import load_config
from navd.daemon.daemon import Daemon
from navd.formats.log import RecordLog
from navd.schema import Published
from navd.settings import ConfigError, config_from_dict


def _check_config(tmp_path: Path, text: str) -> subprocess.CompletedProcess:
    cfg = tmp_path / "navd.yaml"
    cfg.write_text(text)
    return subprocess.run(
        [sys.executable, "-m", "navd.cli", "check-config", str(cfg)],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_a_yaml_bomb_under_a_known_key_is_one_short_line(tmp_path: Path) -> None:
    """Nine levels of nine aliases: 387 million strings if anything wrote it out."""
    levels = ["_: &a [x, x, x, x, x, x, x, x, x]"]
    names = "abcdefghi"
    for i in range(1, 9):
        refs = ", ".join(["*" + names[i - 1]] * 9)
        levels.append(f"_{i}: &{names[i]} [{refs}]")
    # anchors are defined inside the navigation mapping's value list
    doc = "navigation:\n  rate_hz:\n" + "".join(
        f"    - {line.split(': ', 1)[1]}\n" for line in levels
    )
    cfg = tmp_path / "bomb.yaml"
    cfg.write_text(doc)
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as exc:
        load_config(cfg)
    assert time.perf_counter() - t0 < 2.0
    msg = str(exc.value)
    assert "navigation.rate_hz" in msg and len(msg) < 300


def test_a_400_digit_integer_names_its_key(tmp_path: Path) -> None:
    r = _check_config(tmp_path, "navigation:\n  rate_hz: " + "9" * 400 + "\n")
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert "navigation.rate_hz" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_a_duplicate_key_is_an_error_naming_its_line(tmp_path: Path) -> None:
    r = _check_config(tmp_path, "navigation:\n  rate_hz: 10\n  rate_hz: 5\n")
    assert r.returncode == 2
    assert "line 3: duplicate key 'rate_hz'" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize(
    ("key", "doc"),
    [
        ("log.rotate_mb", {"log": {"rotate_mb": 1e-7}}),
        ("devices.modem.ping_interval_s", {"devices": {"modem": {"ping_interval_s": 1e-6}}}),
        ("navigation.speed.rpm_per_mps", {"navigation": {"speed": {"rpm_per_mps": 1e-9}}}),
        ("zenoh.listen[0]", {"zenoh": {"listen": ["tcp/0.0.0.0:7447"]}}),
        ("zenoh.listen[0]", {"zenoh": {"listen": ["tcp/[::]:7447"]}}),
    ],
)
def test_values_that_would_flood_or_expose_the_vehicle_are_refused(key: str, doc: dict) -> None:
    with pytest.raises(ConfigError, match=key.replace("[", r"\[").replace("]", r"\]")):
        config_from_dict(doc)


class _QuietPub:
    """A publisher that publishes nowhere."""

    def section(self) -> dict:
        return {"open": True, "errors": 0, "commands": {}}

    def put(self, out: Published) -> bytes:
        return b""

    def close(self) -> None:
        pass


def _no_devices(tmp_path: Path):  # noqa: ANN202 - a Config
    devices = {n: {"enabled": False} for n in ("ahrs", "gps", "pressure", "motor", "modem")}
    return config_from_dict({"log": {"dir": str(tmp_path / "log")}, "devices": devices})


def test_the_daemon_navigates_while_zenoh_cannot_open(tmp_path: Path) -> None:
    attempts: list[float] = []

    def factory(loop: asyncio.AbstractEventLoop, on_command: object) -> _QuietPub:
        attempts.append(time.monotonic())
        if len(attempts) < 2:
            raise OSError("Address already in use")
        return _QuietPub()

    cfg = _no_devices(tmp_path)

    async def main() -> None:
        d = Daemon(cfg, publisher_factory=factory)
        stop = asyncio.Event()
        task = asyncio.get_running_loop().create_task(d.run(stop))
        await asyncio.sleep(0.5)
        h = d.health()
        assert any(p.startswith("zenoh: not open (OSError") for p in h.degraded)
        assert d.times.ticks >= 3  # the filter ticks without zenoh
        await asyncio.sleep(1.0)
        assert d.pub is not None and d.health().zenoh["open"]
        stop.set()
        await task

    asyncio.run(main())
    assert len(attempts) == 2


def test_a_babbling_device_is_held_to_its_raw_byte_budget(tmp_path: Path) -> None:
    log = RecordLog(tmp_path, raw_budget_bytes_per_s=1000.0)
    for k in range(1000):  # 100 kB in one second
        log.raw_bytes(k * 0.001, "ahrs", b"\x00" * 100)
        log.raw_bytes(k * 0.001, "gps", b"$" * 1)
    log.close()
    text = "".join(f.read_text() for f in tmp_path.glob("*.jsonl"))
    logged_ahrs = text.count('"device":"ahrs"')
    assert 15 <= logged_ahrs <= 25  # the first second's budget and its refill
    assert log.raw_dropped["ahrs"] == (1000 - logged_ahrs) * 100
    assert "gps" not in log.raw_dropped  # another device's budget is its own


def test_the_log_directory_is_kept_under_its_limit(tmp_path: Path) -> None:
    from navd.records import Heading

    log = RecordLog(tmp_path, rotate_mb=0.01, keep_mb=0.05)
    for k in range(20000):
        log.record(Heading(k * 0.1, 90.0))
    log.close()
    total = sum(f.stat().st_size for f in tmp_path.glob("*.jsonl"))
    assert total <= 0.05 * 1024 * 1024 + 0.011 * 1024 * 1024  # the limit, plus the open file
    assert log.removed_files > 0


@pytest.mark.parametrize(
    "endpoint",
    [
        "tcp/0:7612",
        "tcp/[0:0:0:0:0:0:0:0]:7612",
        "tcp/[::ffff:0.0.0.0]:7612",
        "udp/0x0:7612",
        "tcp/192.168.2.10:7447",
        "tcp/example.com:7447",
    ],
)
def test_listen_endpoints_are_parsed_not_matched(endpoint: str) -> None:
    """Spellings of "every interface" (and addresses off the vehicle) that a text match let by."""
    with pytest.raises(ConfigError, match=r"zenoh\.listen\[0\]"):
        config_from_dict({"zenoh": {"listen": [endpoint]}})


def test_an_address_beyond_loopback_is_allowed_when_the_config_says_so() -> None:
    z = {"listen": ["tcp/192.168.2.10:7447"], "listen_beyond_loopback": True}
    assert config_from_dict({"zenoh": z}).zenoh.listen == ["tcp/192.168.2.10:7447"]
    with pytest.raises(ConfigError, match="every interface"):
        config_from_dict({"zenoh": {**z, "listen": ["tcp/0:7447"]}})


@pytest.mark.parametrize("target", ["missing.json5", ".", "/dev/zero", "not-json5"])
def test_check_config_opens_the_zenoh_file_as_navd_run_will(tmp_path: Path, target: str) -> None:
    import subprocess
    import sys

    (tmp_path / "not-json5").write_text("{ mode: peer, ")
    path = target if target.startswith("/") else str(tmp_path / target)
    cfg = tmp_path / "navd.yaml"
    ports = {n: {"port": f"/dev/navd-{n}"} for n in ("ahrs", "gps", "pressure", "motor", "modem")}
    cfg.write_text(yaml.safe_dump({"zenoh": {"config_file": path}, "devices": ports}))
    for cmd, code in ((["check-config"], 2), (["run", "--config"], 78)):
        t0 = time.perf_counter()
        r = subprocess.run(
            [sys.executable, "-m", "navd", *cmd, str(cfg)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert time.perf_counter() - t0 < 30
        assert r.returncode == code, r.stderr
        assert "zenoh.config_file" in r.stderr and len(r.stderr.strip().splitlines()) == 1
        assert "Traceback" not in r.stderr


def test_the_daemon_navigates_while_zenoh_takes_long_to_open(tmp_path: Path) -> None:
    """zenoh.open blocked for seconds (a router that does not answer): in its thread."""

    def factory(loop: asyncio.AbstractEventLoop, on_command: object) -> _QuietPub:
        time.sleep(2.0)  # blocking, as zenoh.open is
        return _QuietPub()

    cfg = _no_devices(tmp_path)

    async def main() -> None:
        d = Daemon(cfg, publisher_factory=factory)
        stop = asyncio.Event()
        task = asyncio.get_running_loop().create_task(d.run(stop))
        await asyncio.sleep(1.5)
        assert d.pub is None and d.times.ticks >= 10  # 10 Hz while zenoh opens
        await asyncio.sleep(1.5)
        assert d.pub is not None
        stop.set()
        await task

    asyncio.run(main())
