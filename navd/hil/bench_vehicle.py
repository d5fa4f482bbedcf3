"""The emulated vehicle on the bench: ``navd-hil demo`` and ``navd run`` as on the vehicle.

One home for starting and stopping the pair, shared by ``make demo``, the daemon
benchmark and the live tests.  Zenoh listens on a free loopback port so that
several bench vehicles (or a test run beside a demo) never collide.
"""

from __future__ import annotations

import math
import signal
import socket
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, cast

import yaml

from navd.files import load_yaml
from navd.formats import jsonlines
from navd.settings import deep_merge

BIN = Path(sys.executable).parent
_COMPARED = ("lat", "lon", "std_n", "std_e", "current_n", "current_e")


@dataclass(frozen=True, slots=True)
class ReplayCheck:
    """How a daemon's log replays against the estimates it published live."""

    returncode: int
    stderr: str
    live: int  # estimates in the log
    common: int  # of those, replayed at the same time
    worst: float  # largest difference over the compared fields


def replay_against_live(logs: list[Path], config: Path, out: Path) -> ReplayCheck:
    """``navd replay`` the daemon's log files and compare with the estimates they hold."""
    r = subprocess.run(
        [str(BIN / "navd"), "replay", *map(str, logs), "--config", str(config), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    live = {o["t"]: o for f in logs for o in log_objects(f) if o.get("type") == "estimate"}
    replayed = {}
    if r.returncode == 0:
        replayed = {o["t"]: o for o in jsonlines.read(out)}
    common = [t for t in live if t in replayed and replayed[t]["type"] == "estimate"]
    worst = max(
        (abs(live[t][k] - replayed[t][k]) for t in common for k in _COMPARED), default=math.inf
    )
    return ReplayCheck(r.returncode, r.stderr, len(live), len(common), worst)


def log_objects(path: Path) -> list[dict[str, Any]]:
    """The JSON objects of a log, without a line the daemon was writing when it was cut
    short (a full disk, a kill): replay skips those too."""
    out = []
    for line in path.read_text().splitlines():
        try:
            o = jsonlines.loads(line)
        except jsonlines.DecodeError:
            continue
        if isinstance(o, dict):
            out.append(o)
    return out


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class BenchVehicle:
    """Emulators on ptys under ``dir`` (config ``dir/navd.yaml``), then the daemon on them."""

    def __init__(
        self,
        d: Path,
        navd_stderr: IO[str] | int | None = None,
        faults: Path | None = None,
        vehicle: str = "sim690s",
        connect: list[str] | None = None,
        state_dir: Path | None = None,
        profile: Path | None = None,
        config: dict[str, Any] | None = None,
    ) -> None:
        """``state_dir``: keep the daemon's checkpoint there (systemd's StateDirectory);
        ``profile``: run the daemon under cProfile, its statistics written there at stop;
        ``config``: keys merged into the vehicle's ``navd.yaml`` before the daemon starts
        (a replay of its log then reads the same file)."""
        self.profile = profile
        self.dir = d
        self.config = d / "navd.yaml"
        self.navd_stderr = navd_stderr
        self.site: list[str] = []
        self.port = free_port()
        args = [str(BIN / "navd-hil"), "demo", "--dir", str(d), "--zenoh-port", str(self.port)]
        args += ["--vehicle", vehicle]
        for endpoint in connect or []:
            args += ["--zenoh-connect", endpoint]
        if faults is not None:
            args += ["--faults", str(faults)]
        self.hil = subprocess.Popen(args, stderr=subprocess.PIPE, text=True)
        self._procs: list[subprocess.Popen[Any]] = [self.hil]  # the daemon goes first, when started
        try:
            assert self.hil.stderr is not None
            # navd-hil writes one line once the emulators serve their ports
            self.banner = self.hil.stderr.readline().strip()
            if not (d / "clock.json").exists():
                raise RuntimeError(f"navd-hil did not start: {self.banner}")
            self.t0_monotonic = jsonlines.loads((d / "clock.json").read_bytes())["t0_monotonic"]
            if config:
                merged = deep_merge(cast(dict[str, object], load_yaml(self.config)), config)
                self.config.write_text(yaml.safe_dump(merged))
            if state_dir is not None:
                state_dir.mkdir(parents=True, exist_ok=True)
                site = d / "state.yaml"
                site.write_text(f"checkpoint: {{dir: '{state_dir}'}}\n")
                self.site = ["--site", str(site)]
            self.navd = self._start_navd()
            self._procs.insert(0, self.navd)
        except BaseException:
            self.kill()  # never leave an emulator running behind a failed start
            raise

    def _start_navd(self) -> subprocess.Popen[bytes]:
        navd = [str(BIN / "navd")]
        if self.profile is not None:
            navd = [sys.executable, "-m", "cProfile", "-o", str(self.profile), "-m", "navd.cli"]
        return subprocess.Popen(
            [*navd, "run", "--config", str(self.config), *self.site], stderr=self.navd_stderr
        )

    def restart_navd(self) -> None:
        """Start the daemon again, as systemd does after a crash or the watchdog."""
        assert self.navd.poll() is not None, "the daemon is still running"
        self.navd = self._start_navd()
        self._procs[0] = self.navd

    def logfiles(self) -> list[Path]:
        """Every log file of the daemon's runs, in order."""
        return sorted((self.dir / "log").glob("*.jsonl"))

    def logfile(self) -> Path:
        """The daemon's log (one file: bench missions are far below the rotation size)."""
        (log,) = sorted((self.dir / "log").glob("*.jsonl"))
        return log

    def stop(self, timeout: float = 30.0) -> None:
        """SIGTERM, as systemd stops the daemon; then the emulators."""
        for p in self._procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                p.wait(timeout=timeout)

    def kill(self) -> None:
        for p in self._procs:
            if p.poll() is None:
                p.kill()
                p.wait()
