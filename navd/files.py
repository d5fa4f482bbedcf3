"""The one way navd opens a file it did not write: configs, overlays, site files, the
zenoh config, scenario and fault files, and logs; and the way it writes a file whole.

A name in a config can point anywhere: at a device (``/dev/zero`` never ends), a
FIFO (opening it blocks until a writer comes), a directory, or a secret
(``/etc/shadow``).  So a file is opened without blocking and without becoming a
controlling terminal, taken only if it is a regular file of bounded size, and
every error is one line naming the file and the problem, never its contents.

YAML goes through :class:`BoundedLoader`: safe tags only, a key given twice
refused, nesting and alias expansion bounded (a 1.4 kB alias bomb expands to
billions of nodes when walked), and integers of more than a few dozen digits
never converted (the schema refuses them, naming the key).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import yaml

from navd.validation import LongInteger, excerpt

__all__ = [
    "FileRefused",
    "MAX_CONFIG_BYTES",
    "BoundedLoader",
    "open_regular",
    "read_regular",
    "read_text",
    "parse_yaml",
    "load_yaml",
    "written_whole",
]

#: a config, overlay, site or zenoh file larger than this is not one
MAX_CONFIG_BYTES = 1 << 20
#: YAML nesting deeper than this is not a config
MAX_YAML_DEPTH = 64
#: nodes a document may expand to, aliases walked as often as they are referenced
MAX_YAML_NODES = 200_000
#: an integer longer than this is a typo or an attack, not a setting
MAX_INT_DIGITS = 30

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class FileRefused(Exception):
    """A file navd will not read; ``str()`` is one line naming it and why."""


def open_regular(path: str | Path, max_bytes: int | None = None) -> IO[bytes]:
    """A regular file opened for reading in binary; refused, in one line, otherwise."""
    p = str(path)
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except OSError as exc:
        raise FileRefused(f"{p}: cannot open ({exc.strerror or exc.__class__.__name__})") from None
    try:
        st = os.fstat(fd)
        for test, kind in _KINDS:
            if test(st.st_mode):
                raise FileRefused(f"{p}: {kind}, not a regular file")
        if not stat.S_ISREG(st.st_mode):
            raise FileRefused(f"{p}: not a regular file")
        if max_bytes is not None and st.st_size > max_bytes:
            raise FileRefused(f"{p}: {st.st_size} bytes, more than the {max_bytes} allowed")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | Path, max_bytes: int = MAX_CONFIG_BYTES) -> bytes:
    """All of a regular file of at most ``max_bytes`` (read bounded, whatever it says
    its size is: a file can grow between the check and the read)."""
    try:
        with open_regular(path, max_bytes) as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        why = exc.strerror or exc.__class__.__name__
        raise FileRefused(f"{path}: cannot read ({why})") from None
    if len(data) > max_bytes:
        raise FileRefused(f"{path}: more than the {max_bytes} bytes allowed")
    return data


def read_text(path: str | Path, max_bytes: int = MAX_CONFIG_BYTES) -> str:
    data = read_regular(path, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise FileRefused(f"{path}: line {line}: not UTF-8 text") from None


class DuplicateKey(yaml.YAMLError):
    def __init__(self, key: Any, line: int) -> None:
        super().__init__(f"line {line}: duplicate key '{excerpt(key, 40)}'")


class YamlTooLarge(yaml.YAMLError):
    pass


class BoundedLoader(yaml.SafeLoader):
    """YAML's safe loader with the bounds a file from anywhere needs."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                mark = self.peek_event().start_mark  # type: ignore[no-untyped-call]
                raise YamlTooLarge(
                    f"line {mark.line + 1}: nested deeper than {MAX_YAML_DEPTH} levels"
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_yaml_int(self, node: yaml.ScalarNode) -> Any:
        digits = sum(c.isdigit() for c in str(node.value))
        if digits > MAX_INT_DIGITS:
            return LongInteger(digits)  # refused by the schema, which names its key
        return super().construct_yaml_int(node)

    def construct_mapping(
        self, node: yaml.MappingNode, deep: bool = False
    ) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                dup = key in seen
                seen.add(key)
            except TypeError:  # an unhashable key: the schema refuses it later
                continue
            if dup:
                raise DuplicateKey(key, key_node.start_mark.line + 1)
        return super().construct_mapping(node, deep=deep)


BoundedLoader.add_constructor(
    "tag:yaml.org,2002:int",
    BoundedLoader.construct_yaml_int,
)


def _over_budget(node: yaml.Node, budget: int) -> str | None:
    """Where the document passes ``budget`` nodes with every alias walked where it is
    used (what a merge or a validation walking it would visit): the dotted key under
    which it does, or None within the budget."""
    count = 0
    stack: list[tuple[yaml.Node, tuple[str, ...]]] = [(node, ())]
    while stack:
        n, path = stack.pop()
        count += 1
        if count > budget:
            return ".".join(path[:2]) or "(top level)"
        if isinstance(n, yaml.MappingNode):
            for k, v in n.value:
                key = k.value if isinstance(k, yaml.ScalarNode) else "?"
                stack.append((k, path))
                stack.append((v, (*path, excerpt(key, 40)) if len(path) < 2 else path))
        elif isinstance(n, yaml.SequenceNode):
            stack.extend((v, path) for v in n.value)
    return None


def parse_yaml(text: str) -> object:
    """One YAML document within the bounds; raises ``yaml.YAMLError`` saying where."""
    loader = BoundedLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        where = _over_budget(node, MAX_YAML_NODES)
        if where is not None:
            raise YamlTooLarge(
                f"{where}: expands to more than {MAX_YAML_NODES} values (aliases repeated"
                " too often)"
            )
        return loader.construct_document(node)
    except RecursionError:
        raise YamlTooLarge("nested too deeply") from None
    finally:
        loader.dispose()


def yaml_error_line(exc: yaml.YAMLError) -> str:
    """A YAML error as one line, never quoting the document."""
    if isinstance(exc, DuplicateKey | YamlTooLarge):
        return str(exc)
    mark = getattr(exc, "problem_mark", None)
    where = f"line {mark.line + 1}: " if mark is not None else ""
    return f"{where}invalid YAML"


def load_yaml(path: str | Path, max_bytes: int = MAX_CONFIG_BYTES) -> object:
    """A YAML file from anywhere: a regular file, bounded, parsed within the bounds.

    Raises :class:`FileRefused` with one line naming the file."""
    text = read_text(path, max_bytes)
    try:
        return parse_yaml(text)
    except yaml.YAMLError as exc:
        raise FileRefused(f"{path}: {yaml_error_line(exc)}") from None


@contextmanager
def written_whole(path: str | Path) -> Iterator[IO[str]]:
    """A text file to write whole.  A regular file, or a new one, is written beside itself
    and renamed over the old at the end, so that no reader sees half of it and a failure
    leaves the old one.  A device, a pipe or a terminal (``/dev/null``, ``/dev/stdout``, a
    FIFO) is written as it is: a file renamed over it would replace it, and as root that
    replaces ``/dev/null`` itself."""
    out = Path(path)
    try:
        regular = stat.S_ISREG(out.stat().st_mode)
    except OSError:
        regular = True  # nothing there (or a dangling link): a new file
    if not regular:
        with out.open("w", encoding="utf-8") as fh:
            yield fh
        return
    tmp = out.with_name(out.name + ".part")
    try:
        with tmp.open("w", encoding="utf-8") as fh:
            yield fh
    except BaseException:
        tmp.unlink(missing_ok=True)  # stopped part way: nothing left behind
        raise
    tmp.replace(out)
