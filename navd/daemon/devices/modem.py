"""The ATM-903 modem as a pinger: kept in command mode, ``ATRX`` every
``ping_interval_s`` with never two outstanding, each ping closed by a range, the
modem's own "no reply", a refusal or navd's timeout."""

from __future__ import annotations

import asyncio

from navd.daemon import pace
from navd.daemon.devices.base import Device, HealthSections, Host, Job
from navd.drivers import modem
from navd.drivers.transport import SerialTransport
from navd.records import Range
from navd.settings import ModemDevice

UNREADY_S = 10.0  # this long outside command mode is said in health
_KEEPER_S = 0.1  # how often the command-mode session is looked after
#: how every ping ended, counted in health's ``pings``
PING_COUNTS = (
    "sent",
    "ranges",
    "fused",  # range decisions the filter made: every range should get one
    "no_reply",
    "refused",  # ERROR, or the shell's "Command '...' not found"
    "timeouts",
    "errors",  # ranges nobody asked for
    "skipped_busy",
    "skipped_not_in_command_mode",
    "skipped_port_down",
)


def _sections(pings: dict[str, int], session: modem.ModemSession) -> HealthSections:
    state = {"mode": session.mode, "ready": session.ready, "escapes": session.escapes}
    return {"pings": dict(pings), "modem": state}


def idle_sections() -> HealthSections:
    """Health's modem sections when navd has no modem (``devices.modem.enabled: false``)."""
    return _sections(dict.fromkeys(PING_COUNTS, 0), modem.ModemSession())


class ModemPinger(Device):
    name = "modem"

    def __init__(self, cfg: ModemDevice, host: Host) -> None:
        self.atm = modem.ModemDecoder()
        super().__init__(cfg, host, self.atm)
        self.modem = cfg
        self.session = modem.ModemSession()
        self.ping_t: float | None = None  # when the outstanding ping left
        self.pings = dict.fromkeys(PING_COUNTS, 0)

    def on_open(self, tr: SerialTransport) -> None:
        self.session.opened(self.host.clock())

    def sections(self) -> HealthSections:
        return _sections(self.pings, self.session)

    def tasks(self) -> list[Job]:
        return [self._keeper(), self._pinger()]

    def on_tick(self, now: float) -> None:
        # a range whose location line never came is complete after a short wait
        for rec in self.atm.expire(now):
            self.handle(rec)

    def every_second(self, now: float) -> None:
        if self.ping_t is not None and now - self.ping_t > self.modem.reply_timeout_s:
            self._ping_lost()

    def on_record(self, rec: object) -> None:
        if isinstance(rec, modem.ModemRange):
            self._on_range(rec)
        elif isinstance(rec, modem.ModemReply):
            self.session.seen(rec)
            self._on_reply(rec)
        elif isinstance(rec, modem.ModemMode):
            self.session.seen(rec)

    def _on_range(self, r: modem.ModemRange) -> None:
        if self.ping_t is None:
            self.pings["errors"] += 1  # a range we did not ask for
            return
        self.pings["ranges"] += 1
        self.host.vitals.ping("range")
        t_ping, self.ping_t = self.ping_t, None
        m = self.modem
        self.host.feed(
            Range(r.t, t_ping, r.range_m, m.beacon, r.lat, r.lon, r.depth, r.twtt_s, r.speed_mps)
        )

    def _on_reply(self, r: modem.ModemReply) -> None:
        # "OK" follows a range, which already closed the ping; silence or a refusal close it
        if r.status == modem.Reply.REFUSED:
            self.pings["refused"] += 1  # counted even when no ping was waiting
        if r.status != modem.Reply.OK and self.ping_t is not None:
            if r.status == modem.Reply.NO_REPLY:
                self.pings["no_reply"] += 1
            self.host.vitals.ping(r.status)
            self.ping_t = None

    def _ping_lost(self) -> None:
        """The modem never closed the last ping, not even with "Response Not Received.":
        it is not listening to commands (online, asleep), so it is brought back."""
        self.pings["timeouts"] += 1
        self.host.vitals.ping("timeout")
        self.ping_t = None
        self.session.lost(self.host.clock())

    async def _pinger(self) -> None:
        m = self.modem
        while True:
            await asyncio.sleep(m.ping_interval_s)
            now = self.host.clock()
            if self.ping_t is not None:
                if now - self.ping_t < m.reply_timeout_s:
                    self.pings["skipped_busy"] += 1
                    continue
                self._ping_lost()
            if not self.connected:
                self.pings["skipped_port_down"] += 1
                continue
            if not self.session.ready:
                self.pings["skipped_not_in_command_mode"] += 1
                continue
            self.ping_t = self.host.clock()
            if self.write(modem.encode_range(m.remote_address)):
                self.pings["sent"] += 1
                self.session.wrote(self.ping_t)
            else:
                self.ping_t = None

    async def _keeper(self) -> None:
        """Bring the modem into command mode and keep it there (ModemSession)."""
        while True:
            await pace.sleep_to_next(_KEEPER_S, self.host.clock)
            if not self.connected:
                continue
            data = self.session.poll(self.host.clock())
            if data:
                self.write(data)

    def own_problems(self, now: float) -> list[str]:
        s = self.session
        if s.t_unready is not None and now - s.t_unready > UNREADY_S:
            return [
                f"modem: not in command mode for {now - s.t_unready:.0f} s "
                f"(last said: {s.mode}, {s.escapes} escapes)"
            ]
        return []
