"""The Castle motor controller: polled for RPM, and one poll in ten for its battery,
current and temperature (health ``esc``)."""

from __future__ import annotations

from navd.daemon.devices.base import Device, HealthSections, Host, Job
from navd.drivers import castle
from navd.drivers.transport import SerialTransport
from navd.records import Rpm
from navd.settings import MotorDevice


class MotorController(Device):
    name = "motor"

    def __init__(self, cfg: MotorDevice, host: Host) -> None:
        self.castle = castle.CastleDecoder(cfg.pole_pairs, cfg.device_id)
        super().__init__(cfg, host, self.castle)
        self.poll_hz = cfg.poll_hz
        self.expected_rate_hz = cfg.poll_hz
        self.esc: dict[str, float] = {}  # battery voltage, current, temperature

    def sections(self) -> HealthSections:
        return {"esc": dict(self.esc)}

    def on_open(self, tr: SerialTransport) -> None:
        tr.write(self.castle.request_clear())  # a half request left in the ESC is dropped

    def tasks(self) -> list[Job]:
        return [self.poll(self.poll_hz, self.castle.request_poll)]

    def on_record(self, rec: object) -> None:
        if isinstance(rec, Rpm):
            self.host.feed(rec)
        elif isinstance(rec, castle.EscStatus):
            self.esc[rec.name] = round(rec.value, 2)
