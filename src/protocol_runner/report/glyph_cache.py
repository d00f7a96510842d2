"""Agg text drawing with its two costly steps cached: the layout of a string and the raster of a glyph.

The report draws ~140 small figures whose text is mostly the same few strings (tick labels, axis labels,
the colour key), and matplotlib's Agg renderer lays out every string and renders every glyph with FreeType
again at each draw: that was half of a figure's drawing time. `CachedTextRenderer.draw_text` does what
`RendererAgg.draw_text` does, step for step, keeping

- the laid-out glyphs of each (string, font properties, dpi) and
- each glyph's rendered bitmap per font, size, angle and sub-pixel offset (the position modulo one
  pixel, in FreeType's 1/64 px units): a glyph moved by whole pixels is the same bitmap moved, so the
  cached bitmap is placed at the new pixel and the image is the same, byte for byte
  (tests/report/test_report_figures.py checks it against matplotlib's own renderer).

It uses matplotlib's private FreeType calls (`FT2Font._layout`, `_set_transform`, `_render_glyph`, as in
matplotlib 3.11's `backend_agg`); where they do not exist (another matplotlib) it draws as matplotlib does.
"""

from __future__ import annotations

import importlib
import math
from typing import Any

import numpy as np
from matplotlib.backends import backend_agg
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.font_manager import FontProperties
from matplotlib.ft2font import FT2Font

#: FreeType's render modes (matplotlib >= 3.11); None before, where the stock path is used
RENDER_MODE: Any = getattr(importlib.import_module("matplotlib.ft2font"), "RenderMode", None)

SUPPORTED = (
    RENDER_MODE is not None
    and all(hasattr(FT2Font, name) for name in ("_layout", "_set_transform", "_render_glyph"))
    and hasattr(RendererAgg, "_prepare_font")
)

#: entries kept per cache before it is emptied (a report uses about 200 strings and 1,500 glyph rasters)
MAX_ENTRIES = 50_000

_LAYOUTS: dict[tuple[Any, ...], tuple[tuple[Any, int, float, float], ...]] = {}
_GLYPHS: dict[tuple[Any, ...], tuple[Any, np.ndarray, int, int]] = {}


class CachedTextRenderer(RendererAgg):
    """`RendererAgg` whose plain (non-math) text reuses laid-out strings and rendered glyphs."""

    def draw_text(
        self,
        gc: Any,
        x: float,
        y: float,
        s: str,
        prop: FontProperties,
        angle: float,
        ismath: bool | str = False,
        mtext: Any = None,
    ) -> None:
        if ismath or not SUPPORTED:
            super().draw_text(gc, x, y, s, prop, angle, ismath=ismath, mtext=mtext)
            return
        flags = backend_agg.get_hinting_flag()
        items = self._layout(s, prop, flags, mtext)
        size = prop.get_size_in_points()
        cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        antialiased = bool(gc.get_antialiased())
        height = self.height
        for font, glyph_index, dx, dy in items:  # dy is upwards, as in RendererAgg
            # FreeType's pen position in 1/64 px, split into whole pixels and the sub-pixel rest
            tx = round(0x40 * (x + dx * cos - dy * sin))
            ty = round(0x40 * (height - y + dx * sin + dy * cos))
            px, rx = divmod(tx, 0x40)
            py, ry = divmod(ty, 0x40)
            key = (id(font), size, self.dpi, glyph_index, angle, rx, ry, antialiased, flags)
            glyph = _GLYPHS.get(key)
            if glyph is None:
                glyph = _GLYPHS[_room(_GLYPHS, key)] = _render(
                    font, size, self.dpi, glyph_index, cos, sin, rx, ry, flags, antialiased
                )
            _, buffer, left, top = glyph
            self._renderer.draw_text_image(
                buffer, left + px, int(height) - (top + py) + buffer.shape[0], 0, gc
            )

    def _layout(
        self, s: str, prop: FontProperties, flags: Any, mtext: Any
    ) -> tuple[tuple[Any, int, float, float], ...]:
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        key = (s, prop, self.dpi, flags, None if features is None else tuple(features), language)
        items = _LAYOUTS.get(key)
        if items is None:
            font = self._prepare_font(prop)
            laid = font._layout(s, flags=flags, features=features, language=language)
            items = tuple((item.ft_object, item.glyph_index, item.x, item.y) for item in laid)
            # the key keeps a copy of the properties: a later change to `prop` cannot alter a stored key
            _LAYOUTS[_room(_LAYOUTS, (s, prop.copy(), *key[2:]))] = items
        return items


def _render(
    font: Any,
    size: float,
    dpi: float,
    glyph_index: int,
    cos: float,
    sin: float,
    rx: int,
    ry: int,
    flags: Any,
    antialiased: bool,
) -> tuple[Any, np.ndarray, int, int]:
    """One glyph rendered at the sub-pixel offset (rx, ry) as RendererAgg renders it: (font, coverage
    bitmap, left, top in pixels relative to the whole-pixel pen position). The font is kept so that its
    id in the cache key stays its own."""
    font.set_size(size, dpi)
    matrix = (0x10000 * np.array([[cos, -sin], [sin, cos]])).round().astype(int)
    font._set_transform(matrix, [rx, ry])
    bitmap = font._render_glyph(glyph_index, flags, RENDER_MODE.NORMAL if antialiased else RENDER_MODE.MONO)
    buffer = np.array(bitmap.buffer)  # a copy: the glyph slot is reused by the next render
    if not antialiased:
        buffer *= 0xFF
    return font, buffer, int(bitmap.left), int(bitmap.top)


def _room(cache: dict[Any, Any], key: Any) -> Any:
    """`key`, after emptying `cache` if it is full (a bound on memory; entries are cheap to redo)."""
    if len(cache) >= MAX_ENTRIES:
        cache.clear()
    return key


class CachedTextCanvas(FigureCanvasAgg):
    """A `FigureCanvasAgg` drawing with `CachedTextRenderer`."""

    def get_renderer(self) -> RendererAgg:
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = CachedTextRenderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer
