"""The report's font files read by FreeType from memory, not from disk (issue 20).

matplotlib opens each font file as a Python file and FreeType reads it through that file, a few bytes at a
time: every glyph a process lays out for the first time costs a seek and a read through Python and the
operating system (about 3,500 per configuration's four figures, the tick labels' digits, axis labels and
keys; a tenth of an analysis worker's drawing time). `read_fonts_from_memory` makes matplotlib's font
loader (`font_manager._get_font`, unchanged: its fallback and last-resort fonts, its per-thread cache)
hand FreeType the file's bytes in memory instead: each file is read once per process, and a forked worker
shares its parent's copy. The font data are the same bytes, so every glyph and every image is the same.

A font's `fname` is then a `FontFile` whose `str()` is the file's path, as matplotlib's own path would be
(the glyph cache keys its rasters by it, `glyph_cache._face`). It replaces `font_manager.ft2font`, the
module name matplotlib 3.11's loader constructs `FT2Font` through, by a stand-in that forwards everything
else; where that name is not there (another matplotlib) nothing is changed.
"""

from __future__ import annotations

import io
import os
import threading
from types import ModuleType
from typing import Any

from matplotlib import font_manager, ft2font

_BYTES: dict[str, bytes] = {}
_LOCK = threading.Lock()


class FontFile(io.BytesIO):
    """A font file's bytes, read once per process; its `str()` is the file's path."""

    def __init__(self, path: str) -> None:
        super().__init__(font_bytes(path))
        self.path = path

    def __str__(self) -> str:
        return self.path

    def __repr__(self) -> str:
        return f"FontFile({self.path!r})"


def font_bytes(path: str) -> bytes:
    """The bytes of the font file at `path`, read on first use and kept for the process."""
    data = _BYTES.get(path)
    if data is None:
        with _LOCK:
            data = _BYTES.get(path)
            if data is None:
                with open(path, "rb") as f:
                    data = _BYTES[path] = f.read()
    return data


class _FromMemory:
    """Stands in for the `ft2font` module in `font_manager`: `FT2Font` of a path reads the file from
    memory; every other name is the module's own."""

    def __init__(self, module: ModuleType) -> None:
        self._module = module

    def __getattr__(self, name: str) -> Any:
        return getattr(self._module, name)

    def FT2Font(self, filename: Any, *args: Any, **kwargs: Any) -> Any:  # matplotlib's name
        if isinstance(filename, (str, bytes, os.PathLike)):
            filename = FontFile(os.fsdecode(filename))
        return self._module.FT2Font(filename, *args, **kwargs)


def read_fonts_from_memory() -> bool:
    """Route matplotlib's font loading through `FontFile`s (once per process); False where matplotlib's
    loader is not as expected, and nothing is changed."""
    current = getattr(font_manager, "ft2font", None)
    if isinstance(current, _FromMemory):
        return True
    if current is not ft2font or not hasattr(font_manager, "_get_font"):
        return False
    font_manager.ft2font = _FromMemory(ft2font)  # type: ignore[assignment,attr-defined]
    font_manager._get_font.cache_clear()  # fonts opened from their files before are opened again
    return True
