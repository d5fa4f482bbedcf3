"""The navigation filter: pure, deterministic, no I/O and no clock."""

from navd.filter.navigator import Navigator
from navd.filter.navparts import make_filter

__all__ = ["Navigator", "make_filter"]
