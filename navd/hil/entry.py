"""The bench's commands, ``navd-sim`` and ``navd-hil``.

The simulator needs the ``sim`` extra (GeographicLib and PROJ, independent of navd's
own geodesy); without it the commands say so in one line.
"""

from __future__ import annotations

import sys


def _missing(prog: str, exc: ModuleNotFoundError) -> int:
    module = (exc.name or "a module").split(".")[0]
    print(f"{prog}: {module} is not installed: pip install 'navd[sim]'", file=sys.stderr)
    return 2


def sim(argv: list[str] | None = None) -> int:
    try:
        from navd.hil.sim_cli import main
    except ModuleNotFoundError as exc:
        return _missing("navd-sim", exc)
    return main(argv)


def hil(argv: list[str] | None = None) -> int:
    try:
        from navd.hil.runner import main
    except ModuleNotFoundError as exc:
        return _missing("navd-hil", exc)
    return main(argv)
