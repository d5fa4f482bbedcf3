"""The one validation engine: a mapping checked into a dataclass, every error one line.

The config, the scenario files, the autopilot's commands and the bench's fault
schedules are all dataclasses whose field types and ``metadata`` bounds are their
schema; :func:`build` walks them.  Measured values (from devices, logs and commands
that carry a position) have their bounds in one table, ``navd.records.BOUNDS``.
"""

from __future__ import annotations

import math
import re
import reprlib
import types
import typing
from dataclasses import MISSING, field, fields, is_dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeVar

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

#: a config section, a command, a scenario: any dataclass a mapping validates into
T = TypeVar("T", bound="DataclassInstance")

__all__ = ["Invalid", "LongInteger", "build", "excerpt", "number", "show", "text"]


class Invalid(Exception):
    """A value that does not fit its schema; ``str()`` names the key and says why."""


def _fail(path: str, msg: str) -> typing.NoReturn:
    raise Invalid(f"{path}: {msg}")


def bounds(
    lo: float | None = None, hi: float | None = None, gt: float | None = None
) -> dict[str, float | None]:
    return {"lo": lo, "hi": hi, "gt": gt}


def number(default: float | None, **kw: float) -> Any:
    """A numeric field with its allowed range: ``lo``, ``hi`` (inclusive), ``gt``."""
    return field(default=default, metadata=bounds(**kw))


def text(default: Any, pattern: str, what: str) -> Any:
    """A string field that must match ``pattern`` whole; ``what`` says so in words."""
    return field(default=default, metadata={"pattern": re.compile(pattern), "what": what})


_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,39}")


def excerpt(value: object, limit: int = 12) -> str:
    """A short, escaped excerpt of what a file said (a key), never more of its bytes."""
    text = value if isinstance(value, str) else repr(value)
    shown = text[:limit].encode("unicode_escape").decode("ascii").replace("'", "\\'")
    return shown + ("..." if len(text) > limit else "")


_SHOW = reprlib.Repr()
_SHOW.maxlevel, _SHOW.maxlist, _SHOW.maxdict = 1, 4, 4
_SHOW.maxstring = _SHOW.maxother = _SHOW.maxlong = 40


def show(value: object) -> str:
    """A value as an error message shows it: bounded, whatever its size or nesting.

    A YAML alias bomb is small as parsed (shared references) and astronomically large
    when written out; the message must never write it out.
    """
    return _SHOW.repr(value)


class LongInteger:
    """What a file's integer of too many digits reads as: never converted (Python's own
    limit raises at 4,300 digits, and the conversion itself is quadratic), so the
    validation can refuse it naming its key."""

    __slots__ = ("digits",)

    def __init__(self, digits: int) -> None:
        self.digits = digits

    def __repr__(self) -> str:
        return f"<an integer of {self.digits} digits>"


def check_number(value: object, tp: type, meta: typing.Mapping[str, Any], path: str) -> float | int:
    if isinstance(value, LongInteger):
        _fail(path, f"an integer of {value.digits} digits")
    if isinstance(value, bool) or not isinstance(value, int | float):
        _fail(path, f"expected a number, got {type(value).__name__} {show(value)}")
    try:
        as_float = float(value)
    except OverflowError:
        _fail(path, f"must be finite, got an integer of {len(str(abs(value)))} digits")
    if tp is int and not (isinstance(value, int) or as_float.is_integer()):
        _fail(path, f"expected a whole number, got {value!r}")
    if not math.isfinite(as_float):
        _fail(path, f"must be finite, got {value!r}")
    lo, hi, gt = meta.get("lo"), meta.get("hi"), meta.get("gt")
    if lo is not None and value < lo:
        _fail(path, f"must be >= {lo:g}, got {value!r}")
    if hi is not None and value > hi:
        _fail(path, f"must be <= {hi:g}, got {value!r}")
    if gt is not None and value <= gt:
        _fail(path, f"must be > {gt:g}, got {value!r}")
    return int(value) if tp is int else float(value)


def convert(value: Any, tp: Any, meta: typing.Mapping[str, Any], path: str) -> Any:
    """``value`` as the schema type ``tp``, or a one-line :class:`Invalid` naming ``path``."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return convert(value, args[0], meta, path)
    if origin is Literal:
        choices = typing.get_args(tp)
        if value not in choices:
            _fail(path, f"must be one of {', '.join(map(str, choices))}, got {show(value)}")
        return value
    if origin is list:
        return _list(value, tp, meta, path)
    if origin is dict:
        return _mapping(value, tp, path)
    if isinstance(tp, type) and is_dataclass(tp):
        return build(tp, value, path)
    if tp in (float, int):
        return check_number(value, tp, meta, path)
    if tp is str:
        return _text(value, meta, path)
    if tp is bool:
        if not isinstance(value, bool):
            _fail(path, f"expected true or false, got {show(value)}")
        return value
    raise TypeError(f"unsupported schema type {tp!r} at {path}")  # a bug in the schema, not input


def _list(value: object, tp: Any, meta: typing.Mapping[str, Any], path: str) -> list[Any]:
    if not isinstance(value, list):
        _fail(path, f"expected a list, got {type(value).__name__}")
    (it,) = typing.get_args(tp)
    return [convert(v, it, meta, f"{path}[{i}]") for i, v in enumerate(value)]


def _mapping(value: object, tp: Any, path: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        _fail(path, f"expected a mapping, got {type(value).__name__}")
    _, vt = typing.get_args(tp)
    out = {}
    for k, v in value.items():
        if not isinstance(k, str) or not k or not k.isprintable():
            _fail(path, f"names must be non-empty printable strings, got {show(k)}")
        out[k] = convert(v if v is not None else {}, vt, {}, f"{path}.{k}")
    return out


def _text(value: object, meta: typing.Mapping[str, Any], path: str) -> str:
    if not isinstance(value, str):
        _fail(path, f"expected a string, got {type(value).__name__} {show(value)}")
    pattern = meta.get("pattern")
    if pattern is not None and not pattern.fullmatch(value):
        _fail(path, f"must be {meta.get('what', pattern.pattern)}, got {show(value)}")
    return value


def build(cls: type[T], data: object, path: str = "") -> T:
    """Validate a mapping into the dataclass ``cls``: unknown keys, types, finiteness and
    each field's ``metadata`` bounds, every error one line naming the dotted key."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        _fail(path or "(top level)", f"expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in fields(cls)}
    for key in data:
        if key not in known:
            # a key is shown as written when it looks like one; anything else (a line of
            # a file that is no config, such as /etc/shadow) only as a short excerpt
            name = key if isinstance(key, str) and _KEY.fullmatch(key) else f"'{excerpt(key)}'"
            _fail(f"{path}.{name}" if path else name, "unknown key")
    kwargs = {}
    for name, f in known.items():
        sub = f"{path}.{name}" if path else name
        if name in data:
            kwargs[name] = convert(data[name], hints[name], f.metadata, sub)
        elif f.default is MISSING and f.default_factory is MISSING:  # pragma: no cover
            _fail(sub, "missing")
    return cls(**kwargs)
