"""The layers of docs/architecture.md, checked over the import graph of the source.

Each module may import its own layer and the ones below; the daemon and the
post-mission analysis are side by side and do not import each other.  Imports
inside functions count too: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

NAVD = Path(__file__).resolve().parent.parent / "navd"

FOUNDATION = {
    "navd",
    "navd.records",
    "navd.geodesy",
    "navd.acoustics",
    "navd.schema",
    "navd.settings",
    "navd.validation",
    "navd.utc",
    "navd.files",
    "navd.endpoints",
    "navd.formats.jsonlines",
}
#: (layer, prefix); the first prefix that matches names a module's layer
LAYERS = [
    (2, "navd.drivers"),
    (3, "navd.filter"),
    (4, "navd.formats"),
    (5, "navd.config"),
    (5, "navd.zenohconf"),
    (6, "navd.daemon"),
    (6, "navd.analysis"),
    (7, "navd.client"),
    (7, "navd.watch"),
    (7, "navd.foxglove_bridge"),
    (7, "navd.cli"),
    (7, "navd.__main__"),
    (7, "navd.hil"),
]
SIDE_BY_SIDE = {("navd.daemon", "navd.analysis"), ("navd.analysis", "navd.daemon")}


def layer(module: str) -> tuple[int, str]:
    if module in FOUNDATION:
        return 1, "foundation"
    for n, prefix in LAYERS:
        if module == prefix or module.startswith(prefix + "."):
            return n, prefix
    raise AssertionError(f"{module} is in no layer of docs/architecture.md")


def modules() -> dict[str, Path]:
    out = {}
    for p in NAVD.rglob("*.py"):
        parts = list(p.relative_to(NAVD.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def imports(path: Path, known: set[str]) -> set[str]:
    """The navd modules a file imports (``from pkg import module`` names the module)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if not node.module.startswith("navd"):
                continue
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                out.add(sub if sub in known else node.module)
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("navd")}
    return out


def test_every_import_goes_down_the_layers() -> None:
    mods = modules()
    known = set(mods)
    wrong = []
    for name, path in sorted(mods.items()):
        n, own = layer(name)
        for dep in sorted(imports(path, known) & known):
            m, theirs = layer(dep)
            if m > n or (own, theirs) in SIDE_BY_SIDE:
                wrong.append(f"{name} ({own}) imports {dep} ({theirs})")
    assert not wrong, "\n".join(wrong)


def test_the_check_sees_a_wrong_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("from navd.daemon.daemon import Daemon\n")
    assert imports(bad, set(modules())) == {"navd.daemon.daemon"}
    assert layer("navd.filter.ekf")[0] < layer("navd.daemon.daemon")[0]


def test_the_navigation_core_and_the_decoders_load_without_yaml() -> None:
    """The filter takes its settings as dataclasses: reading YAML is the config layer's."""
    code = (
        "import sys, navd.filter, navd.drivers.gps, navd.drivers.modem, navd.settings; "
        "print('yaml' in sys.modules)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "False"


def test_one_list_of_devices_for_the_daemon_capture_and_the_bench() -> None:
    import typing

    from navd.daemon.devices import DEVICE_CLASSES
    from navd.hil.runner import Emulators, FaultDevice
    from navd.settings import DEVICE_NAMES

    assert DEVICE_NAMES == ("ahrs", "gps", "pressure", "motor", "modem")
    assert tuple(DEVICE_CLASSES) == DEVICE_NAMES
    assert all(DEVICE_CLASSES[n].name == n for n in DEVICE_NAMES)  # type: ignore[attr-defined]
    assert Emulators.__slots__ == DEVICE_NAMES
    assert typing.get_args(FaultDevice) == DEVICE_NAMES
