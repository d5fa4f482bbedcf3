"""JSON Schema (draft 2020-12) of navd's records, from their dataclasses.

The fields are defined once, in navd/schema.py and navd/records.py; an MCAP file's
JSON channels carry this, so a viewer such as Foxglove can offer each field for a plot.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

_SCALARS: dict[Any, dict[str, Any]] = {
    float: {"type": "number"},
    int: {"type": "integer"},
    bool: {"type": "boolean"},
    str: {"type": "string"},
}


def _of(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        parts = [_of(a) for a in typing.get_args(tp)]
        return {"anyOf": parts} if len(parts) > 1 else parts[0]
    if tp is type(None):
        return {"type": "null"}
    if tp in _SCALARS:
        return dict(_SCALARS[tp])
    if origin is list:
        (item,) = typing.get_args(tp) or (Any,)
        return {"type": "array", "items": _of(item)}
    if origin is dict:
        args = typing.get_args(tp)
        return {"type": "object", "additionalProperties": _of(args[1]) if args else {}}
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return schema_of(tp, title=None)
    return {}  # Any: whatever it holds


def schema_of(cls: type, title: str | None = "") -> dict[str, Any]:
    """The schema of one record type; fields it does not declare are allowed (newer navd)."""
    hints = typing.get_type_hints(cls)
    props = {f.name: _of(hints[f.name]) for f in dataclasses.fields(cls)}
    out: dict[str, Any] = {"type": "object", "properties": props, "additionalProperties": True}
    if title is not None:
        out["title"] = title or cls.__name__
    if "type" in props:
        props["type"] = {"type": "string"}
    return out
