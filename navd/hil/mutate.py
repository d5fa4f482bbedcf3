"""Unlucky and hostile files, made from good ones: what the property tests and
``make bench-files`` feed replay.

A mutation is ``(kind, where, byte, dt)``: ``where`` in [0, 1] picks the line, ``byte``
the value a flip writes, ``dt`` the step a time jump adds.  Kinds: a byte flipped, a line
duplicated, two lines swapped, a line deleted, a line's time moved, the file cut
short in the middle of a line.
"""

from __future__ import annotations

from navd.formats import jsonlines

KINDS = ("flip", "duplicate", "swap", "delete", "time", "truncate")
JUMPS = (-1e9, -3600.0, -5.0, -0.5, 0.3, 2.0, 50.0, 1e4, 1e9)

Mutation = tuple[str, float, int, float]


def set_t(line: str, t: float) -> str:
    obj = jsonlines.loads(line)
    obj["t"] = t
    return jsonlines.dumps_line(obj)


def mutate(lines: list[str], muts: list[Mutation]) -> tuple[bytes, int]:
    """The mutated file's bytes (after its header), and how many lines it touched.

    Mutations apply one after another, each to what the ones before left (a time moved
    on a line a flip already broke leaves it broken)."""
    out = [ln.encode() for ln in lines]
    touched = 0
    for kind, where, byte, dt in muts:
        if len(out) < 3:
            break  # cut to nothing already
        i = min(len(out) - 2, int(where * (len(out) - 1)))
        if kind == "flip":
            b = bytearray(out[i])
            b[int(where * 997) % max(1, len(b) - 1)] = byte
            out[i] = bytes(b)
            touched += 2 if byte == 10 else 1  # a new line end splits the line in two
        elif kind == "duplicate":
            out.insert(i, out[i])
            touched += 1
        elif kind == "swap":
            out[i], out[i + 1] = out[i + 1], out[i]
            touched += 2
        elif kind == "delete":
            del out[i]
            touched += 1
        elif kind == "time":
            try:
                t = jsonlines.loads(out[i])["t"]
                out[i] = set_t(out[i].decode(), max(-1e9, min(1e9, t + dt))).encode()
            except (ValueError, RecursionError, KeyError, TypeError):  # orjson's, UTF-8's
                pass  # a line broken already stays broken
            touched += 1
        else:  # truncate
            touched += len(out) - i
            out = [*out[:i], out[i][: len(out[i]) // 2]]
    return b"".join(out), touched
