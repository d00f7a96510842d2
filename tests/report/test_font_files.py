"""The report's fonts read from memory (report/font_files.py): the same glyphs, each file read once."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib import font_manager
from matplotlib.ft2font import FT2Font, LoadFlags

from protocol_runner.report import font_files
from protocol_runner.report.canvas import canvas_axes
from protocol_runner.report.font_files import FontFile, read_fonts_from_memory

TEXT = "Torque (N m) 0.25 -12 Hysteresis"


def _dejavu() -> str:
    return str(font_manager.findfont(font_manager.FontProperties(family="DejaVu Sans")))


def _raster(font: FT2Font) -> tuple[np.ndarray, tuple[int, int]]:
    font.set_size(11, 100)
    font.set_text(TEXT, 0.0, flags=LoadFlags.FORCE_AUTOHINT)
    font.draw_glyphs_to_bitmap()
    return np.asarray(font.get_image()).copy(), font.get_width_height()


def test_a_font_from_memory_draws_the_same_glyphs_as_from_its_file() -> None:
    path = _dejavu()
    from_file, size_file = _raster(FT2Font(path))
    from_memory, size_memory = _raster(FT2Font(FontFile(path)))
    assert size_memory == size_file
    assert from_memory.any()  # glyphs were drawn
    np.testing.assert_array_equal(from_memory, from_file)


def test_matplotlib_loads_fonts_from_memory_once_routed(monkeypatch: pytest.MonkeyPatch) -> None:
    """After the routing, matplotlib's own loader hands FreeType a `FontFile` (str(): the path, which the
    glyph cache keys by), and a file is read from disk once however many fonts are opened from it."""
    monkeypatch.setattr(font_files, "_BYTES", {})
    reads: list[str] = []
    real_open = open

    def counting_open(file, *args, **kwargs):  # type: ignore[no-untyped-def]
        reads.append(str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", counting_open)
    assert read_fonts_from_memory()
    assert read_fonts_from_memory()  # once: a second call changes nothing
    path = _dejavu()
    font_manager._get_font.cache_clear()
    font = font_manager.get_font(path)
    assert isinstance(font.fname, FontFile)
    assert str(font.fname) == path
    font_manager._get_font.cache_clear()
    again = font_manager.get_font(path)
    assert again is not font  # opened anew, from the bytes already read
    assert reads.count(path) == 1
    assert _raster(again)[0].any()


def test_report_canvases_route_the_fonts() -> None:
    canvas_axes("single")
    assert isinstance(font_manager.ft2font, font_files._FromMemory)
    assert font_manager.ft2font.LoadFlags is LoadFlags  # every other name is the module's own
