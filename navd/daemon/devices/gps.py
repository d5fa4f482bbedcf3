"""The GPS receiver, on its serial port (NMEA) or through gpsd (JSON): fixes to the
filter, its UTC to health and to the navigator's tidal prediction."""

from __future__ import annotations

import datetime as dt

from navd.daemon.devices.base import Device, HealthSections, Host
from navd.drivers import gps, gpsd
from navd.drivers.transport import SerialTransport
from navd.records import Clock, Gps
from navd.settings import GpsDevice

NMEA_MAX_HZ = 10.0  # GGA and RMC at 5 Hz, the fastest a navigation receiver is set to
# the receiver's UTC goes to the navigator (and the log) at its first valid fix and then
# this often: the computer's clock drifts far slower than that
CLOCK_EVERY_S = 60.0


class GpsReceiver(Device):
    name = "gps"
    expected_rate_hz = NMEA_MAX_HZ

    def __init__(self, cfg: GpsDevice, host: Host) -> None:
        decoder = gpsd.GpsdDecoder() if cfg.source == "gpsd" else gps.NmeaDecoder()
        super().__init__(cfg, host, decoder)
        self.gpsd = cfg.source == "gpsd"
        self.utc: dt.datetime | None = None  # the receiver's last UTC (RMC, or gpsd's TPV)
        self._clock_t: float | None = None  # when the receiver's UTC was last passed on

    def sections(self) -> HealthSections:
        # against t_utc of the estimates, the system clock's error
        return {"gps_utc": self.utc.isoformat() if self.utc else None}

    def on_open(self, tr: SerialTransport) -> None:
        if self.gpsd:
            tr.write(gpsd.WATCH)  # on every connect: gpsd forgets a watch with its client

    def on_record(self, rec: object) -> None:
        if isinstance(rec, Gps):
            self.host.feed(rec)
        elif isinstance(rec, gps.GpsTime):
            self.utc = rec.utc or self.utc
            if rec.valid and rec.utc is not None and (
                self._clock_t is None or rec.t - self._clock_t >= CLOCK_EVERY_S
            ):
                # the tidal prediction's clock (navd/filter/navigator.py), logged with
                # the measurements so that a replay reads the prediction as the daemon did
                self._clock_t = rec.t
                self.host.feed(Clock(rec.t, rec.utc.timestamp()))
