"""Where a command writes (figures, bags, tables), checked before it does any work.

A study that runs for minutes and then cannot write its figures has wasted the minutes and said
nothing: every verb checks its output paths first, with one line naming the option, the path and
why. The check writes a probe file and removes it at once, because permission bits do not tell
(root passes ``os.access`` on a read-only file system, on /proc and on /sys); a folder that does
not exist yet is probed in its nearest existing parent and is not made here.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import ConfigError, PredictiveDriveError

__all__ = ["check_output_dir", "check_output_file", "unwritable"]


def _existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (every path has one: the root)."""
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def unwritable(path: str | Path) -> str | None:
    """Why a folder at ``path`` could not be made or written into (None: it can). ``path`` may
    exist (then it must be a folder) or not (then its nearest existing ancestor must be one)."""
    p = Path(path)
    here = _existing(p)
    if not here.is_dir():
        return f"{here} is a file, not a folder"
    try:
        with tempfile.TemporaryFile(dir=here, prefix=".write-check-"):
            pass
    except OSError as e:
        return f"{here} is not writable ({e.strerror or e})"
    return None


def check_output_dir(
    path: str | Path | None, *, option: str, error: type[PredictiveDriveError] = ConfigError
) -> Path | None:
    """The folder ``option`` names, checked writable (made later, by what writes into it);
    ``error`` (ConfigError) names the option, the path and why not. None passes through."""
    if path is None:
        return None
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise error(f"{option} {p}: a file of that name exists, not a folder")
    why = unwritable(p)
    if why is not None:
        raise error(f"{option} {p}: cannot write there: {why}")
    return p


def check_output_file(path: str | Path, *, option: str) -> Path:
    """The file ``option`` names, checked before the work: not a folder, and its folder
    writable (it need not exist yet)."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"{option} {p}: a folder, not a file")
    why = unwritable(p.parent if str(p.parent) else Path(os.curdir))
    if why is not None:
        raise ConfigError(f"{option} {p}: cannot write it: {why}")
    return p
