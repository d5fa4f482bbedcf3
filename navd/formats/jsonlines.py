"""JSON Lines encoding and decoding in one place, with orjson where it is installed.

Replay reads and writes hundreds of thousands of lines; orjson does that several
times faster than the standard library.  Both reject what JSON does not allow
(orjson refuses ``NaN`` literals when reading, navd never writes a non-finite
number), and both write floats that read back to the same value (the text of very
small numbers differs: ``5.1e-05`` against ``0.000051``).  A non-finite number
is written ``null`` by orjson and refused by the standard library: the filter's
outputs are checked finite before they get here.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

try:
    import orjson
except ImportError:  # pragma: no cover - orjson is a dependency; the fallback is for vendors
    orjson = None  # type: ignore[assignment]

__all__ = [
    "loads", "loads_unique", "dumps", "dumps_line", "read", "DecodeError", "DuplicateKey",
    "JsonObject", "object_or_none",
]

#: a JSON object as decoded, its values to be checked for their types where they are used
JsonObject = dict[str, object]


def object_or_none(value: object) -> JsonObject | None:
    """``value`` if it is a JSON object (a dict with string keys), else None."""
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return value
    return None


class DuplicateKey(ValueError):
    """A JSON object that names a key twice (JSON keeps the last, silently)."""


def _refuse_duplicates(pairs: list[tuple[str, object]]) -> JsonObject:
    out: JsonObject = {}
    for k, v in pairs:
        if k in out:
            raise DuplicateKey(k)
        out[k] = v
    return out


def loads_unique(text: str | bytes) -> object:
    """``loads`` for a small message whose meaning a repeated key could change (a
    command: ``{"force": false, "force": true}``); raises DuplicateKey or a DecodeError.
    The standard library's parser, for its hook: commands are at most a few kB."""
    return json.loads(text, object_pairs_hook=_refuse_duplicates, parse_constant=_no_constant)


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not JSON")  # NaN, Infinity: as orjson refuses them

if orjson is not None:
    DecodeError: tuple[type[Exception], ...] = (orjson.JSONDecodeError, RecursionError)

    def loads(text: str | bytes) -> Any:
        return orjson.loads(text)

    _OPTS = orjson.OPT_SERIALIZE_NUMPY  # a numpy scalar that reached an output is a number

    def dumps(obj: object) -> bytes:
        return orjson.dumps(obj, option=_OPTS)

    def dumps_line(obj: object) -> str:
        return orjson.dumps(obj, option=_OPTS).decode() + "\n"

else:  # pragma: no cover
    DecodeError = (json.JSONDecodeError, RecursionError)
    _enc = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode

    def loads(text: str | bytes) -> Any:
        return json.loads(text)

    def dumps(obj: object) -> bytes:
        return _enc(obj).encode()

    def dumps_line(obj: object) -> str:
        return _enc(obj) + "\n"


def read(path: str | Path) -> list[Any]:
    """Every non-blank line of a file we wrote ourselves (outputs, truth).

    Logs from elsewhere go through :mod:`navd.formats.mlog`, which skips and counts
    malformed lines; here a malformed line raises ``DecodeError``.
    """
    with open(path, "rb") as fh:
        return [loads(line) for line in fh if line.strip()]
