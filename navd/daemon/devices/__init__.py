"""One object per serial device, the way DUNE gives each device a task.

A device owns its decoder, its open sequence, what it asks and how often, what its
records mean to navd, and what health says of it.  The daemon opens a port for each,
feeds their bytes in and ticks them; it knows no device by name.
"""

from __future__ import annotations

from navd.daemon.devices.ahrs import Ahrs
from navd.daemon.devices.base import Device, Host
from navd.daemon.devices.gps import GpsReceiver
from navd.daemon.devices.modem import ModemPinger
from navd.daemon.devices.motor import MotorController
from navd.daemon.devices.pressure import PressureSensor
from navd.settings import Config

__all__ = [
    "Ahrs",
    "Device",
    "GpsReceiver",
    "Host",
    "ModemPinger",
    "MotorController",
    "PressureSensor",
    "make_devices",
]


def make_devices(cfg: Config, host: Host) -> dict[str, Device]:
    """The enabled devices, by the name their config section has."""
    d = cfg.devices
    made: list[Device] = []
    if d.ahrs.enabled:
        made.append(Ahrs(d.ahrs, host))
    if d.gps.enabled:
        made.append(GpsReceiver(d.gps, host))
    if d.pressure.enabled:
        made.append(PressureSensor(d.pressure, host))
    if d.motor.enabled:
        made.append(MotorController(d.motor, host))
    if d.modem.enabled:
        made.append(ModemPinger(d.modem, host))
    return {dev.name: dev for dev in made}
