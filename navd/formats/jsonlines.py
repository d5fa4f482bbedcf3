"""JSON Lines encoding and decoding in one place, with orjson where it is installed.

Replay reads and writes hundreds of thousands of lines; orjson does that several
times faster than the standard library.  Both reject what JSON does not allow
(orjson refuses ``NaN`` literals when reading, navd never writes a non-finite
number), and both write floats that read back to the same value (the text of very
small numbers differs: ``5.1e-05`` against ``0.000051``).
"""

from __future__ import annotations

import json
from typing import Any

try:
    import orjson
except ImportError:  # pragma: no cover - orjson is a dependency; the fallback is for vendors
    orjson = None  # type: ignore[assignment]

__all__ = ["loads", "dumps_line", "DecodeError"]

if orjson is not None:
    DecodeError: tuple[type[Exception], ...] = (orjson.JSONDecodeError, RecursionError)

    def loads(text: str | bytes) -> Any:
        return orjson.loads(text)

    def dumps_line(obj: Any) -> str:
        return orjson.dumps(obj).decode() + "\n"

else:  # pragma: no cover
    DecodeError = (json.JSONDecodeError, RecursionError)
    _enc = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode

    def loads(text: str | bytes) -> Any:
        return json.loads(text)

    def dumps_line(obj: Any) -> str:
        return _enc(obj) + "\n"
