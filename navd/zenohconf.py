"""A zenoh JSON5 config file (credentials, TLS, access control), read the one way:
as every file from elsewhere (:mod:`navd.files`), then parsed by zenoh.

The daemon (``zenoh.config_file``), :class:`navd.client.NavClient` and the tools
(``navd watch``, ``navd foxglove``: ``--zenoh-config``) all read theirs here.
"""

from __future__ import annotations

import zenoh

from navd import files
from navd.settings import ConfigError


def read_zenoh_file(path: str, what: str = "zenoh.config_file") -> zenoh.Config:
    """The file as a zenoh config; :class:`ConfigError` in one line naming ``what`` and
    the file, never quoting it beyond the start of zenoh's own message."""
    try:
        text = files.read_text(path)
    except files.FileRefused as exc:
        raise ConfigError(f"{what}: {exc}") from None
    try:
        return zenoh.Config.from_json5(text)
    except Exception as exc:  # zenoh's ZError
        first = (str(exc).splitlines() or [exc.__class__.__name__])[0][:80]
        raise ConfigError(f"{what}: {path}: zenoh refuses it ({first})") from None
