"""Compass deviation: the heading error hard and soft iron give, as a function of heading.

A magnetic compass near iron reads the magnetic heading plus a deviation that
depends on the heading itself.  To the first two harmonics (N. Bowditch, *The
American Practical Navigator*, NGA Pub. 9, chapter "Magnetic compass adjustment":
the approximate coefficients A to E):

    deviation(h) = A + B sin h + C cos h + D sin 2h + E cos 2h

A is a constant (misalignment, and what the filter's heading-bias state can
learn), B and C come from hard iron (one cycle per turn), D and E from soft iron
(two cycles).  Seed 000's Chesapeake runs had an AHRS never calibrated for them.
Here ``h`` is the heading the compass reads, so the correction is explicit:
magnetic = compass - deviation(compass).  ``navd calibrate compass`` fits the five
coefficients; ``navigation.compass_deviation_deg`` carries them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

TERMS = 5  # A, B, C, D, E


def basis(h_deg: float) -> tuple[float, float, float, float, float]:
    h = math.radians(h_deg)
    return 1.0, math.sin(h), math.cos(h), math.sin(2 * h), math.cos(2 * h)


def deviation_deg(coeffs: Sequence[float], h_deg: float) -> float:
    """The deviation (degrees) at compass heading ``h_deg``; none without coefficients."""
    if not coeffs:
        return 0.0
    return sum(c * b for c, b in zip(coeffs, basis(h_deg), strict=True))


def correct(coeffs: Sequence[float], compass_deg: float) -> float:
    """The magnetic heading, in [0, 360), from the compass's reading."""
    return (compass_deg - deviation_deg(coeffs, compass_deg)) % 360.0
