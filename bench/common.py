"""What the benchmarks share: a config per filter mode, and BENCHMARKS.md sections."""

from __future__ import annotations

from pathlib import Path

import yaml

from navd.analysis.replay import replay_outputs
from navd.config import load_config
from navd.schema import Output
from navd.settings import deep_merge


def mode_config(mission_dir: Path, mode: str) -> Path:
    """The mission's crew config with ``navigation.filter`` set."""
    cfg = mission_dir / f"config-{mode}.yaml"
    if not cfg.exists():
        crew = yaml.safe_load((mission_dir / "config.yaml").read_text()) or {}
        cfg.write_text(yaml.safe_dump(deep_merge(crew, {"navigation": {"filter": mode}})))
    return cfg


def replay_mission(
    mission_dir: Path, mode: str, smooth: bool = False
) -> tuple[list[Output], str]:
    """What ``navd replay MISSION/measurements.jsonl --config <mode's>`` writes, and the
    error it would end with ("" when none), run in this process: a worker that replays
    hundreds of missions starts Python and imports navd once, and keeps the outputs
    rather than writing and reading them back."""
    try:
        cfg = load_config(mode_config(mission_dir, mode))
        return replay_outputs(mission_dir / "measurements.jsonl", cfg, smooth=smooth), ""
    except Exception as exc:  # a mission that makes navd raise is a result, not a crash
        return [], f"{exc.__class__.__name__}: {exc}"


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
