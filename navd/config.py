"""A config file as navd reads it: YAML with its overlays, sites on top, and where
systemd puts files; the schema itself is :mod:`navd.settings`."""

from __future__ import annotations

import typing
from pathlib import Path

from navd import files
from navd.settings import Config, ConfigError, config_from_dict, deep_merge

__all__ = ["load_config", "read_with_overlays", "log_dir", "default_config_path"]


DEV_LOG_DIR = "navd-log"


def log_dir(cfg: Config, env: typing.Mapping[str, str]) -> str:
    """Where the log goes: ``log.dir``, else systemd's LogsDirectory, else ./navd-log."""
    return cfg.log.dir or env.get("LOGS_DIRECTORY", "").split(":")[0] or DEV_LOG_DIR


def default_config_path(env: typing.Mapping[str, str]) -> str | None:
    """navd.yaml in systemd's ConfigurationDirectory, when navd runs under it."""
    d = env.get("CONFIGURATION_DIRECTORY", "").split(":")[0]
    return f"{d}/navd.yaml" if d else None


MAX_OVERLAY_DEPTH = 8  # overlays of overlays: deeper is a loop or a mistake


def _read_yaml(p: Path) -> object:
    try:
        return files.load_yaml(p)
    except files.FileRefused as exc:
        raise ConfigError(str(exc)) from None


def read_with_overlays(p: Path, depth: int = 0) -> dict[str, object]:
    """A config file with its ``overlays`` merged on top, in order, each relative to it.

    A site file is an overlay on the vehicle's file: ``overlays: [sites/claytor-lake.yaml]``
    in navd.yaml, and the site's values win.  An empty file is an empty mapping.
    """
    if depth > MAX_OVERLAY_DEPTH:
        raise ConfigError(f"{p}: overlays nested deeper than {MAX_OVERLAY_DEPTH} (a loop?)")
    raw = _read_yaml(p)
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ConfigError(f"{p}: expected a mapping of sections, got {type(raw).__name__}")
    # a key that is no string is refused by name when the config is validated
    data: dict[str, object] = dict(raw)
    names = data.pop("overlays", [])
    if isinstance(names, str):
        names = [names]
    if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
        raise ConfigError(f"{p}: overlays: expected a file name or a list of them")
    for name in names:
        data = deep_merge(data, read_with_overlays(p.parent / name, depth + 1))
    return data


def load_config(path: str | Path | None, sites: typing.Sequence[str | Path] = ()) -> Config:
    """Load and validate a YAML config file with its overlays, then ``sites`` on top;
    ``None`` and no sites gives all defaults."""
    if path is None and not sites:
        return Config()
    data: dict[str, object] = {}
    named = []
    for f in [*([path] if path is not None else []), *sites]:
        data = deep_merge(data, read_with_overlays(Path(f)))
        named.append(str(f))
    try:
        return config_from_dict(data)
    except ConfigError as exc:
        raise ConfigError(f"{' + '.join(named)}: {exc}") from None
