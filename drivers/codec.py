"""What every sans-I/O device codec shares: the decoder's counters and its contract.

A decoder is fed bytes as they arrive (any split, any garbage) and returns the
typed records completed by them.  It never blocks, never sleeps and never raises
on bad bytes: it counts what it skipped and resynchronises (the h11/wsproto
pattern).  Time stamps are the caller's: ``feed(data, t)`` stamps every record
completed by ``data`` with ``t``, the arrival time of those bytes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol


@dataclass(slots=True)
class DecodeStats:
    """Counters every decoder keeps; health reports them."""

    bytes_in: int = 0
    records: int = 0
    skipped_bytes: int = 0  # garbage and the bytes of rejected frames
    bad_checksum: int = 0
    bad_frame: int = 0  # well delimited but unparseable or out of range
    reasons: dict[str, int] = field(default_factory=dict)

    def bad(self, reason: str) -> None:
        """A well-framed record whose content is unusable (NaN, out of range)."""
        self.bad_frame += 1
        self.reasons[reason] = self.reasons.get(reason, 0) + 1

    def skip(self, n: int, reason: str) -> None:
        self.skipped_bytes += n
        self.reasons[reason] = self.reasons.get(reason, 0) + 1


class Decoder(Protocol):
    stats: DecodeStats

    def feed(self, data: bytes, t: float) -> list[object]: ...
