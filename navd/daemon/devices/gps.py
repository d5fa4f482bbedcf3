"""The NMEA GPS receiver: fixes to the filter, its UTC to health."""

from __future__ import annotations

import datetime as dt

from navd.config import SerialPortConfig
from navd.daemon.devices.base import Device, Host
from navd.drivers import gps
from navd.records import Gps

NMEA_MAX_HZ = 10.0  # GGA and RMC at 5 Hz, the fastest a navigation receiver is set to


class GpsReceiver(Device):
    name = "gps"
    expected_rate_hz = NMEA_MAX_HZ

    def __init__(self, cfg: SerialPortConfig, host: Host) -> None:
        super().__init__(cfg, host, gps.NmeaDecoder())
        self.utc: dt.datetime | None = None  # the receiver's last UTC (RMC)

    def on_record(self, rec: object) -> None:
        if isinstance(rec, Gps):
            self.host.feed(rec)
        elif isinstance(rec, gps.GpsTime):
            self.utc = rec.utc or self.utc
