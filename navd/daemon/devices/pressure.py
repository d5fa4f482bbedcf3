"""The Keller PA-30X: initialised and asked its serial number on every open, polled
for pressure; its temperature goes to health."""

from __future__ import annotations

import logging

from navd.daemon.devices.base import Device, HealthSections, Host, Job
from navd.drivers import keller
from navd.drivers.transport import SerialTransport
from navd.records import Pressure
from navd.settings import PressureDevice


class PressureSensor(Device):
    name = "pressure"

    def __init__(self, cfg: PressureDevice, host: Host) -> None:
        self.keller = keller.KellerDecoder(cfg.address, cfg.local_echo)
        super().__init__(cfg, host, self.keller)
        self.poll_hz = cfg.poll_hz
        self.expected_rate_hz = cfg.poll_hz
        self.temperature_c: float | None = None

    def sections(self) -> HealthSections:
        return {"temperature_c": self.temperature_c}

    def on_open(self, tr: SerialTransport) -> None:
        tr.write(self.keller.request_init())
        tr.write(self.keller.request_serial())  # which sensor: in health and the journal

    def tasks(self) -> list[Job]:
        return [self.poll(self.poll_hz, lambda: self.keller.request(keller.CH_PRESSURE))]

    def on_record(self, rec: object) -> None:
        if isinstance(rec, Pressure):
            self.host.feed(rec)
        elif isinstance(rec, keller.Temperature):
            self.temperature_c = rec.c
        elif isinstance(rec, keller.SerialNumber):
            if self.info.get("serial_number") != rec.number:
                logging.getLogger("navd").info("%s: serial number %d", self.name, rec.number)
            self.info["serial_number"] = rec.number
