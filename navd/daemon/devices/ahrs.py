"""The 3DM-GX3-25 AHRS: set up on every open, streaming Euler angles, soft-reset when
an open unit falls silent."""

from __future__ import annotations

import asyncio
import math

from navd.daemon.devices.base import Device, Host
from navd.drivers import ahrs
from navd.drivers.transport import SerialTransport
from navd.settings import AhrsDevice

PROBE_WAIT_S = 3.0  # a device asked who it is answers within this
RESET_S = 10.0  # an open AHRS silent this long is soft-reset (at most this often)
RESET_WAIT_S = 1.0  # from the soft reset to setting it up again


class Ahrs(Device):
    name = "ahrs"

    def __init__(self, cfg: AhrsDevice, host: Host) -> None:
        self.gx3 = ahrs.AhrsDecoder()
        super().__init__(cfg, host, self.gx3)
        self.rate_hz = cfg.rate_hz
        self.expected_rate_hz = cfg.rate_hz
        self.t_probe: float | None = None  # since when the unit has been asked who it is
        self.t_probe_sent = -math.inf  # when it was last asked
        self.eeprom: dict[int, int] = {}
        self.t_reset = -math.inf  # the last soft reset navd sent

    def on_open(self, tr: SerialTransport) -> None:
        tr.write(ahrs.encode_stop())
        # which unit is this: a single-byte 3DM-GX3-25 answers with its firmware;
        # was its compass ever calibrated: its hard-iron offsets
        self.t_probe = self.t_probe_sent = self.host.clock()
        self.info.clear()
        self.eeprom.clear()
        tr.write(ahrs.encode_firmware_probe())
        tr.write(self.gx3.request_hard_iron())
        tr.write(ahrs.encode_sampling(self.rate_hz))
        tr.write(ahrs.encode_continuous())

    def on_record(self, rec: object) -> None:
        if isinstance(rec, ahrs.Euler):
            self.host.feed(rec.attitude)
        elif isinstance(rec, ahrs.Firmware):
            self.info["firmware"] = rec.version
        elif isinstance(rec, ahrs.EepromWord):
            self.eeprom[rec.address] = rec.value
            words = [self.eeprom.get(ahrs.HARD_IRON_ADDR + 2 * i) for i in range(6)]
            if all(w is not None for w in words):
                offsets = ahrs.hard_iron([w for w in words if w is not None])
                self.info["hard_iron"] = [
                    round(x, 6) if math.isfinite(x) else None for x in offsets
                ]

    def every_second(self, now: float) -> None:
        """An AHRS whose port is open but which has said nothing for ``RESET_S`` is
        soft-reset and set up again (as after an open): a unit that lost its settings
        in a brown-out streams nothing until told again."""
        tr = self.transport
        if not tr.health.connected:
            return
        if "firmware" not in self.info and now - self.t_probe_sent > PROBE_WAIT_S:
            # unanswered (a stalled or resetting unit): ask again until it says who it is
            self.t_probe_sent = now
            tr.write(ahrs.encode_firmware_probe())
            if "hard_iron" not in self.info:
                tr.write(self.gx3.request_hard_iron())
        last = max(tr.health.last_rx or -math.inf, self.t_probe or -math.inf, self.t_reset)
        if now - last < RESET_S:
            return
        self.t_reset = now
        self.resets += 1
        tr.write(ahrs.encode_soft_reset())
        asyncio.get_running_loop().call_later(RESET_WAIT_S, self.on_open, tr)

    def own_problems(self, now: float) -> list[str]:
        if (
            self.t_probe is not None
            and "firmware" not in self.info
            and now - self.t_probe > PROBE_WAIT_S
            and self.connected
        ):
            return [
                f"{self.name}: no answer to the firmware probe: not a single-byte protocol unit?"
            ]
        return []
