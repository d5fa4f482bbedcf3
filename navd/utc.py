"""UTC times as text: the one reading of them for the config, the logs and the filter."""

from __future__ import annotations

import datetime as dt
import math

__all__ = ["utc_seconds", "utc_time"]

_MAX_CHARS = 64  # an ISO 8601 time with microseconds and its zone is about 32


def utc_time(text: object) -> dt.datetime | None:
    """An ISO 8601 time with its zone (``2016-04-14T15:20:00Z``, gpsd's ``time``); None for
    anything else, a time without a zone too (it is local to someone)."""
    if not isinstance(text, str) or len(text) > _MAX_CHARS:
        return None
    try:
        when = dt.datetime.fromisoformat(text.strip())
    except ValueError:
        return None
    return when if when.utcoffset() is not None else None


def utc_seconds(text: object) -> float | None:
    """:func:`utc_time` as seconds since the Unix epoch."""
    when = utc_time(text)
    if when is None:
        return None
    try:
        s = when.timestamp()
    except (OverflowError, OSError, ValueError):
        return None
    return s if math.isfinite(s) else None
