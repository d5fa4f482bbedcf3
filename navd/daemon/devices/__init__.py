"""One object per serial device, the way DUNE gives each device a task.

A device owns its decoder, its open sequence, what it asks and how often, what its
records mean to navd, and what health says of it.  The daemon opens a port for each,
feeds their bytes in and ticks them; it knows no device by name.
"""

from __future__ import annotations

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
