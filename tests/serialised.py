"""Outputs as navd writes and publishes them: what the tests compare with the schema."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from navd.schema import Published, to_dict


def rows(outputs: Iterable[Published | dict[str, Any]]) -> list[dict[str, Any]]:
    """The serialised form of each output (a row read from a file is one already)."""
    return [o if isinstance(o, dict) else to_dict(o) for o in outputs]
