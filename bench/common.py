"""What the benchmarks share: a config per filter mode, and BENCHMARKS.md sections."""

from __future__ import annotations

from pathlib import Path

import yaml

from navd.config import deep_merge


def mode_config(mission_dir: Path, mode: str) -> Path:
    """The mission's crew config with ``navigation.filter`` set."""
    cfg = mission_dir / f"config-{mode}.yaml"
    if not cfg.exists():
        crew = yaml.safe_load((mission_dir / "config.yaml").read_text()) or {}
        cfg.write_text(yaml.safe_dump(deep_merge(crew, {"navigation": {"filter": mode}})))
    return cfg


def write_section(path: Path, name: str, heading: str, body: str) -> None:
    """Replace (or append) the section between ``<!-- name:begin/end -->`` markers."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    section = f"{begin}\n{body}\n{end}"
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        text = head + section + rest.split(end, 1)[1]
    else:
        text = text.rstrip() + f"\n\n## {heading}\n\n" + section + "\n"
    path.write_text(text)


def report(body: str, write: str | None, target: str, title: str) -> None:
    """Print a benchmark's section and, with ``--write FILE``, put it under ``## title``."""
    print(body)
    if write:
        write_section(Path(write), target, f"{title} (`make {target}`)", body)
