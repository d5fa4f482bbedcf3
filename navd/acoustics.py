"""Sound speed and acoustic travel time: the one place in navd that knows about sound in water.

References
----------
* K. V. Mackenzie, "Nine-term equation for sound speed in the oceans", JASA 70(3), 1981
  (seed 000 eq. 3.1).  Valid for -2..30 degC, 30..40 ppt, 0..8000 m.
* A. B. Coppens, "Simple equations for the speed of sound in Neptunian waters",
  JASA 69(3), 1981 (seed 000 eq. 3.2).  Valid for 0..35 degC, 0..45 ppt, 0..4000 m.
* Round-trip travel time with the transponder's turnaround time: Techy et al.,
  seed 004 eq. 1.
"""

from __future__ import annotations

from dataclasses import dataclass

from navd.records import Range, TravelTime

__all__ = [
    "mackenzie",
    "coppens",
    "validity_warnings",
    "SoundSpeed",
    "travel_time_to_range",
    "rescale_range",
]

# (min, max) of temperature degC, salinity ppt, depth m where each equation holds.
_VALIDITY = {
    "mackenzie": ((-2.0, 30.0), (30.0, 40.0), (0.0, 8000.0)),
    "coppens": ((0.0, 35.0), (0.0, 45.0), (0.0, 4000.0)),
}


def mackenzie(temperature_c: float, salinity_ppt: float, depth_m: float) -> float:
    """Sound speed in m/s from Mackenzie's nine-term equation (eq. 3.1)."""
    t, s, d = temperature_c, salinity_ppt, depth_m
    return (
        1448.96
        + 4.591 * t
        - 5.304e-2 * t**2
        + 2.374e-4 * t**3
        + 1.340 * (s - 35.0)
        + 1.630e-2 * d
        + 1.675e-7 * d**2
        - 1.025e-2 * t * (s - 35.0)
        - 7.139e-13 * t * d**3
    )


def coppens(temperature_c: float, salinity_ppt: float, depth_m: float) -> float:
    """Sound speed in m/s from Coppens' equation (eq. 3.2); depth is given in metres."""
    t = temperature_c / 10.0
    s = salinity_ppt - 35.0
    d = depth_m / 1000.0  # the equation takes kilometres
    c0 = 1449.05 + 45.7 * t - 5.21 * t**2 + 0.23 * t**3 + (1.333 - 0.126 * t + 0.009 * t**2) * s
    return (
        c0 + (16.23 + 0.253 * t) * d + (0.213 - 0.1 * t) * d**2 + (0.016 + 0.0002 * s) * s * t * d
    )


def validity_warnings(
    model: str, temperature_c: float, salinity_ppt: float, depth_m: float
) -> list[str]:
    """Human-readable warnings for inputs outside the model's published range."""
    if model not in _VALIDITY:
        return []
    out = []
    names = ("temperature_c", "salinity_ppt", "depth_m")
    for name, value, (lo, hi) in zip(
        names, (temperature_c, salinity_ppt, depth_m), _VALIDITY[model], strict=True
    ):
        if not lo <= value <= hi:
            out.append(f"{model}: {name}={value:g} outside its validity range [{lo:g}, {hi:g}]")
    return out


@dataclass(frozen=True, slots=True)
class SoundSpeed:
    """The water's sound speed as configured (``navigation.sound_speed``)."""

    model: str = "coppens"
    temperature_c: float = 10.0
    salinity_ppt: float = 0.2
    fixed_mps: float = 1500.0
    modem_mps: float = 1500.0

    def at(self, depth_m: float) -> float:
        """Sound speed in the water at ``depth_m`` (m/s)."""
        d = max(0.0, depth_m)
        if self.model == "mackenzie":
            return mackenzie(self.temperature_c, self.salinity_ppt, d)
        if self.model == "coppens":
            return coppens(self.temperature_c, self.salinity_ppt, d)
        return self.fixed_mps

    def warnings(self, depth_m: float = 0.0) -> list[str]:
        return validity_warnings(self.model, self.temperature_c, self.salinity_ppt, depth_m)


def travel_time_to_range(twtt_s: float, sound_speed_mps: float, turnaround_s: float = 0.0) -> float:
    """One-way range from a round-trip time less the transponder's turnaround (seed 004 eq. 1)."""
    return 0.5 * sound_speed_mps * (twtt_s - turnaround_s)


def rescale_range(range_m: float, modem_mps: float, water_mps: float) -> float:
    """Correct a range the modem computed with its own sound speed to the water's sound speed.

    The modem measured a time and multiplied it by ``modem_mps``; the same time with
    the water's speed gives the true range.
    """
    return range_m * (water_mps / modem_mps)


def slant_range(
    rec: Range | TravelTime,
    water_mps: float,
    modem_mps: float,
    turnaround_s: float,
    as_reported: bool = False,
) -> float:
    """The range a record gives, with the water's sound speed ``water_mps``.

    A travel time is turned into a range after the beacon's turnaround.  A modem's
    range is re-derived from its own round trip when it reports one (right whatever
    sound speed the modem was set to), else rescaled from the modem's sound speed;
    ``as_reported`` keeps the modem's range as it is (the thesis does).
    """
    if isinstance(rec, TravelTime):
        return travel_time_to_range(rec.twtt_s, water_mps, turnaround_s)
    if as_reported:
        return rec.m
    if rec.twtt_s is not None:
        return travel_time_to_range(rec.twtt_s, water_mps, 0.0)
    return rescale_range(rec.m, modem_mps, water_mps)
