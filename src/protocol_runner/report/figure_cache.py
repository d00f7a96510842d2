"""Configuration figures drawn ahead of the report: a cache next to the archive, keyed by what is drawn.

The session's analysis workers draw each configuration's figures as soon as its fit is written
(`session/early_figures.py`) and store them here, one JSON file per configuration in `figures/` beside
`archive.h5`. The report uses a stored figure only when its fingerprint matches the configuration it
has just read from the archive: the fingerprint covers every field the configuration figures read
(`FIGURE_FIELDS`), the figure code (`FIGURE_CODE`) and the matplotlib version. Anything else
(no cache, a re-processed archive, a newer figure style, a damaged file) is drawn again, so the report
shows the same figures with or without the cache.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
from pathlib import Path

import numpy as np

from protocol_runner import __version__
from protocol_runner.report.html_file import write_atomically
from protocol_runner.report.model import Configuration

CACHE_DIR_NAME = "figures"

#: The modules whose code decides what a stored figure looks like.
FIGURE_CODE = (
    "protocol_runner.report.figures",
    "protocol_runner.report.canvas",
    "protocol_runner.report.glyph_cache",
    "protocol_runner.report.png",
)

#: The `Configuration` fields the configuration figures read (figures.configuration_tasks).
FIGURE_FIELDS = ("key", "trials", "energy_loss_j", "energy_cycle_trial", "bouc_wen", "element_fit")


def cache_dir_of(archive_path: str | Path) -> Path:
    """The figure cache of the archive at `archive_path` (a folder beside it)."""
    return Path(archive_path).parent / CACHE_DIR_NAME


@functools.cache
def _code_identity() -> bytes:
    """The figure code and the library that draws: a change to either invalidates every stored figure.
    (The library's version from its installed metadata: a process that only assembles the report, its
    figures drawn by others, never imports matplotlib.)"""
    h = hashlib.sha256(f"{__version__} matplotlib {_matplotlib_version()}".encode())
    for module in FIGURE_CODE:
        spec = importlib.util.find_spec(module)
        origin = spec.origin if spec is not None else None
        try:
            h.update(Path(origin).read_bytes() if origin else module.encode())
        except OSError:
            h.update(module.encode())
    return h.digest()


def _matplotlib_version() -> str:
    try:
        return importlib.metadata.version("matplotlib")
    except importlib.metadata.PackageNotFoundError:  # not installed as a distribution: ask the module
        import matplotlib

        return str(matplotlib.__version__)


def _feed(h: hashlib._Hash, value: object) -> None:
    """Add `value` (dataclasses, sequences, arrays, scalars) to `h`, type and shape included."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        h.update(f"<{type(value).__name__}".encode())
        for f in dataclasses.fields(value):
            h.update(f.name.encode())
            _feed(h, getattr(value, f.name))
        h.update(b">")
    elif isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        h.update(f"<array {array.dtype.str} {array.shape}>".encode())
        h.update(array.tobytes())
    elif isinstance(value, (tuple, list)):
        h.update(f"<seq {len(value)}".encode())
        for item in value:
            _feed(h, item)
        h.update(b">")
    elif value is None or isinstance(value, (str, int, float, bool, np.generic)):
        h.update(f"<{type(value).__name__} {value!r}>".encode())
    else:
        raise TypeError(f"cannot fingerprint a {type(value).__name__}")


def fingerprint(cfg: Configuration) -> str:
    """A digest of everything the configuration's figures show, and of the code that draws them."""
    h = hashlib.sha256(_code_identity())
    for name in FIGURE_FIELDS:
        h.update(name.encode())
        _feed(h, getattr(cfg, name))
    return h.hexdigest()


def _path(cache_dir: Path, cfg: Configuration) -> Path:
    return cache_dir / f"{cfg.name}.json"


def save(cache_dir: Path, cfg: Configuration, images: dict[str, str]) -> None:
    """Store the configuration's figures (atomically: a reader sees the old file, the new one or none)."""
    cache_dir.mkdir(parents=True, exist_ok=True)
    write_atomically(_path(cache_dir, cfg), json.dumps({"fingerprint": fingerprint(cfg), "images": images}))


def has_entry(cache_dir: Path, cfg: Configuration) -> bool:
    """Whether figures of `cfg` were stored at all (whatever data they were drawn from): without an entry
    they are surely drawn anew, known without reading or fingerprinting anything."""
    return _path(cache_dir, cfg).is_file()


def lookup(cache_dir: Path, cfg: Configuration) -> dict[str, str] | None:
    """The stored figures of `cfg` if they were drawn from exactly this data by this code, else None."""
    try:
        stored = json.loads(_path(cache_dir, cfg).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(stored, dict) or stored.get("fingerprint") != fingerprint(cfg):
        return None
    images = stored.get("images")
    if not isinstance(images, dict) or not all(isinstance(v, str) for v in images.values()):
        return None
    return images
