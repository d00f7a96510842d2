"""Where a protocol may read files from: its own folder, and the protocols shipped with the package.

A protocol names trajectory files, calibration tables and a reference dataset. Each path must stay inside
the protocol's folder, both as written (relative, no `..` out of it, so the session can store a copy at
the same place) and after symlinks are resolved; or it is an absolute path into the shipped protocols
folder (read from the installation). Anything else is refused before the file is opened, so no message
can show a line of a file the protocol had no right to read.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..resources import packaged_protocols_dir


class OutsideFolder(Exception):
    """A referenced path the protocol may not read; the message names the path as written."""


def confined_path(base: Path, written: str) -> Path:
    """The file `written` (as in the protocol) refers to, or `OutsideFolder` if the protocol may not read it."""
    shipped = packaged_protocols_dir().resolve()
    try:
        given = Path(written)
        target = (base / given).resolve()
        inside_base = target.is_relative_to(base.resolve())
    except (OSError, ValueError, RuntimeError):  # a NUL byte, a symlink loop, ...
        raise OutsideFolder(f"{written!r} is not a usable file path") from None
    if given.is_absolute():
        if target.is_relative_to(shipped):
            return target
        raise OutsideFolder(
            f"{written} is an absolute path outside the shipped protocols; give a path relative to the "
            "protocol's folder"
        )
    escapes = os.path.normpath(written).split(os.sep)[0] == ".."
    if escapes or not (inside_base or target.is_relative_to(shipped)):
        raise OutsideFolder(
            f"{written} lies outside the protocol's folder; put the file next to the protocol "
            "(or in a folder below it)"
        )
    return base / given


def is_stored_with_session(written: str) -> bool:
    """Whether a confined path is copied into the session (relative ones); absolute ones are shipped."""
    return not Path(written).is_absolute()
