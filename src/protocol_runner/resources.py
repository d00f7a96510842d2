"""Where the shipped data lives: protocols and report templates.

In an installed wheel they are inside the package (`protocol_runner/_data/...`); in a source checkout
(including an editable install) they are at the repository root (`protocols/`, `reports/templates/`).
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent
_REPO_ROOT = _PACKAGE_DIR.parent.parent


def _first_existing(*candidates: Path) -> Path:
    for candidate in candidates:
        if candidate.is_dir():
            return candidate
    return candidates[0]


def packaged_protocols_dir() -> Path:
    """The directory of the protocols shipped with the package."""
    return _first_existing(_PACKAGE_DIR / "_data" / "protocols", _REPO_ROOT / "protocols")


def templates_dir() -> Path:
    """The directory of the report's jinja2 templates."""
    return _first_existing(_PACKAGE_DIR / "_data" / "templates", _REPO_ROOT / "reports" / "templates")


def packaged_rigs_dir() -> Path:
    """The directory of the rig files shipped inside the package (`rig: rsst`)."""
    return _PACKAGE_DIR / "rigs"
