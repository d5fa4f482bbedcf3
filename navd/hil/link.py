"""Driving the device emulators from the world simulator in real time.

Mission time is ``clock() - t0``; each emulator reads the world at that time.  The
modem's acoustic link lives here; ``navd/hil/runner.py`` moves the other emulators along
the mission.
"""

from __future__ import annotations

from collections.abc import Callable

from navd.hil.world import Mission


def modem_range_fn(
    mission: Mission, t0: float
) -> Callable[[float], tuple[float, float, float | None, float | None, float | None] | None]:
    """A ``range_to`` for the modem emulator (ModemEmulator) from the mission's channel."""

    def range_to(
        t_mono: float,
    ) -> tuple[float, float, float | None, float | None, float | None] | None:
        r = mission.channel.ping(t_mono - t0)
        if r is None:
            return None
        return r.t - r.t_ping, r.m, r.beacon_lat, r.beacon_lon, r.beacon_depth

    return range_to
