"""One object per serial device, the way DUNE gives each device a task.

A device owns its decoder, its open sequence, what it asks and how often, what its
records mean to navd, its port (opened when the daemon starts it), and what health
says of it.  The daemon starts them, feeds their records to the filter and ticks
them; it knows no device by name.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

from navd.daemon.devices.ahrs import Ahrs
from navd.daemon.devices.base import Device, Host
from navd.daemon.devices.gps import GpsReceiver
from navd.daemon.devices.modem import ModemPinger
from navd.daemon.devices.motor import MotorController
from navd.daemon.devices.pressure import PressureSensor
from navd.settings import DEVICE_NAMES, Config, device_config

__all__ = [
    "Ahrs",
    "DEVICE_CLASSES",
    "Device",
    "GpsReceiver",
    "Host",
    "ModemPinger",
    "MotorController",
    "PressureSensor",
    "make_devices",
    "wait_open",
]


#: each device's class, by the name of its config section (navd.settings.DEVICE_NAMES)
DEVICE_CLASSES: dict[str, Callable[[Any, Host], Device]] = {
    "ahrs": Ahrs,
    "gps": GpsReceiver,
    "pressure": PressureSensor,
    "motor": MotorController,
    "modem": ModemPinger,
}


def make_devices(cfg: Config, host: Host) -> dict[str, Device]:
    """The enabled devices, by the name their config section has, in its order."""
    made = {}
    for name in DEVICE_NAMES:
        section = device_config(cfg.devices, name)
        if section.enabled:
            made[name] = DEVICE_CLASSES[name](section, host)
    return made


async def wait_open(
    devices: dict[str, Device], clock: Callable[[], float], within_s: float
) -> list[str]:
    """Wait until every port is open, or ``within_s`` has shown which are not; those are
    returned, each said in the journal with why (the journal is where a crew looks
    first)."""
    t_end = clock() + within_s
    while clock() < t_end and not all(d.connected for d in devices.values()):
        await asyncio.sleep(0.05)
    down = [n for n, d in devices.items() if not d.connected]
    for name in down:
        why = devices[name].transport.health.last_error or "no answer yet"
        logging.getLogger("navd").warning("%s: not open (%s); retrying", name, why)
    return down
