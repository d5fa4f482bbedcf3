"""``navd capture``: record what one real device sends, to settle protocol facts.

The daemon runs with only that device enabled, asking it exactly what it asks in
service (the open sequence, the polls, the pings), without zenoh, logging every
byte the port delivers.  ``raw_frames`` reads the bytes back, so a test can feed
them to the device's decoder as golden vectors (docs/protocols.md, "Check against
the hardware").
"""

from __future__ import annotations

import asyncio
import dataclasses
from pathlib import Path
from typing import Any

from navd import files
from navd.formats.jsonlines import loads
from navd.settings import DEVICE_NAMES, Config, ConfigError, device_config


def capture_config(cfg: Config, device: str, out_dir: str | Path) -> Config:
    """``cfg`` with only ``device`` enabled and every byte of it logged to ``out_dir``."""
    if device not in DEVICE_NAMES:
        raise ConfigError(f"capture: no device {device!r} (one of {', '.join(DEVICE_NAMES)})")
    dev = device_config(cfg.devices, device)
    if not dev.port:
        raise ConfigError(f"devices.{device}.port: required to capture from it")
    # each section keeps its own type; the mapping is by name, so mypy sees the base class
    sections: dict[str, Any] = {
        name: dataclasses.replace(device_config(cfg.devices, name), enabled=name == device)
        for name in DEVICE_NAMES
    }
    devices = dataclasses.replace(cfg.devices, **sections)
    log = dataclasses.replace(
        cfg.log, dir=str(out_dir), raw_bytes=True, raw_budget_bytes_per_s=1e8, keep_mb=0.0
    )
    return dataclasses.replace(cfg, devices=devices, log=log)


def capture(cfg: Config, device: str, seconds: float, out_dir: str | Path) -> Path | None:
    """Run the capture; returns the log file written (None if the port never opened)."""
    from navd.daemon.daemon import Daemon

    daemon = Daemon(capture_config(cfg, device, out_dir))

    async def main() -> None:
        stop = asyncio.Event()
        asyncio.get_running_loop().call_later(seconds, stop.set)
        await daemon.run(stop)

    asyncio.run(main())
    dev = daemon.devices[device]
    if dev.transport.health.opens == 0:
        why = dev.transport.health.last_error or "never opened"
        raise ConfigError(f"capture: devices.{device}.port {dev.cfg.url}: {why}")
    return daemon.rlog.path


def raw_frames(path: str | Path, device: str) -> list[tuple[float, bytes]]:
    """The bytes ``device`` delivered, with their arrival times, from a daemon log."""
    out = []
    with files.open_regular(path) as fh:
        for line in fh:
            try:
                obj = loads(line)
                if not (isinstance(obj, dict) and obj.get("type") == "raw"):
                    continue
                if obj.get("device") == device:
                    out.append((float(obj["t"]), bytes.fromhex(obj["hex"])))
            except (KeyError, TypeError, ValueError, RecursionError):  # orjson's errors too
                continue  # a line cut by a kill, or corrupt: the rest still counts
    return out
