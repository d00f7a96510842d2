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

Font objects are matplotlib's, per thread and per process as matplotlib keeps them (a FreeType face read
by two processes at once through an inherited file fails): laid-out strings are kept per thread and
forgotten in a forked child; glyph rasters, plain arrays, are keyed by the font file and face, not the object.

A text artist's layout (`Text._get_layout`: its box, lines and offsets relative to its anchor, independent
of where it is drawn) is kept too, for text drawn on these canvases: matplotlib computes it again for every
extent query and every draw (a tick label twice per figure), and the report's labels repeat from figure to
figure. It is keyed by everything the layout reads (`_text_layout_key`), so a label whose text, font,
alignment or rotation changes is laid out anew.

It uses matplotlib's private FreeType calls (`FT2Font._layout`, `_set_transform`, `_render_glyph`, as in
matplotlib 3.11's `backend_agg`); where they do not exist (another matplotlib) it draws as matplotlib does.
"""

from __future__ import annotations

import importlib
import math
import os
import threading
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.backends import backend_agg
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.font_manager import FontProperties, fontManager, get_font
from matplotlib.ft2font import FT2Font
from matplotlib.text import Text
from matplotlib.transforms import Bbox

#: FreeType's render modes (matplotlib >= 3.11); None before, where the stock path is used
RENDER_MODE: Any = getattr(importlib.import_module("matplotlib.ft2font"), "RenderMode", None)

SUPPORTED = (
    RENDER_MODE is not None
    and all(hasattr(FT2Font, name) for name in ("_layout", "_set_transform", "_render_glyph"))
    and hasattr(RendererAgg, "_prepare_font")
)

#: entries kept per cache before it is emptied (a report uses about 200 strings and 1,500 glyph rasters)
MAX_ENTRIES = 50_000

#: a laid-out string: per glyph its font, the font's `_face`, the glyph index and its offset (px)
Layout = tuple[tuple[Any, tuple[str, str], int, float, float], ...]

_LAYOUTS: dict[tuple[Any, ...], Layout] = {}
_GLYPHS: dict[tuple[Any, ...], tuple[np.ndarray, int, int]] = {}
_HEIGHTS: dict[tuple[Any, ...], tuple[float | None, ...]] = {}
_EXTENTS: dict[tuple[Any, ...], Any] = {}
_TEXT_LAYOUTS: dict[tuple[Any, ...], tuple[np.ndarray, list[Any], Any]] = {}

if hasattr(os, "register_at_fork"):  # a forked child opens its own fonts (matplotlib empties its cache too)
    os.register_at_fork(after_in_child=_LAYOUTS.clear)


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
        # what else decides a glyph's raster: FreeType's load flags and matplotlib's hinting factor
        flags = _hinting_flag(), mpl.rcParams._get("text.hinting_factor")
        items = self._layout(s, prop, flags, mtext)
        x, y = float(x), float(y)  # the same doubles; Python floats round faster than numpy scalars
        size = prop.get_size_in_points()
        cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        antialiased = bool(gc.get_antialiased())
        height = self.height
        for font, face, glyph_index, dx, dy in items:  # dy is upwards, as in RendererAgg
            # FreeType's pen position in 1/64 px, split into whole pixels and the sub-pixel rest
            tx = round(0x40 * (x + dx * cos - dy * sin))
            ty = round(0x40 * (height - y + dx * sin + dy * cos))
            px, rx = divmod(tx, 0x40)
            py, ry = divmod(ty, 0x40)
            key = (face, size, self.dpi, glyph_index, angle, rx, ry, antialiased, flags)
            glyph = _GLYPHS.get(key)
            if glyph is None:
                glyph = _GLYPHS[_room(_GLYPHS, key)] = _render(
                    font, size, self.dpi, glyph_index, cos, sin, rx, ry, flags, antialiased
                )
            buffer, left, top = glyph
            self._renderer.draw_text_image(
                buffer, left + px, int(height) - (top + py) + buffer.shape[0], 0, gc
            )

    def get_text_width_height_descent(self, s: str, prop: FontProperties, ismath: Any) -> Any:
        """The size of a plain string as `RendererAgg` measures it (FreeType lays the string out), kept per
        string, font and size for every renderer: matplotlib keeps it per renderer, and the report's three
        canvases measure the same tick labels."""
        if ismath or not SUPPORTED:
            return super().get_text_width_height_descent(s, prop, ismath)
        rc = mpl.rcParams._get
        flags = _hinting_flag(), rc("text.hinting_factor"), rc("text.kerning_factor")
        key = (s, prop.copy(), self.dpi, *flags)
        size = _EXTENTS.get(key)
        if size is None:
            size = _EXTENTS[_room(_EXTENTS, key)] = super().get_text_width_height_descent(s, prop, ismath)
        return size

    def _get_font_height_metrics(self, prop: FontProperties) -> tuple[float | None, ...]:
        """The font's ascent, descent and line gap (px) that `Text._get_layout` otherwise reads from the
        font's tables for every string it lays out, computed as it does and kept per font and size."""
        key = (prop.copy(), self.dpi)
        metrics = _HEIGHTS.get(key)
        if metrics is None:
            metrics = _HEIGHTS[_room(_HEIGHTS, key)] = _font_height_metrics(prop, self.dpi)
        return metrics

    def _layout(self, s: str, prop: FontProperties, flags: Any, mtext: Any) -> Layout:
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        options = (None if features is None else tuple(features), language, threading.get_ident())
        key = (s, prop, self.dpi, flags, *options)
        items = _LAYOUTS.get(key)
        if items is None:
            font = self._prepare_font(prop)
            laid = font._layout(s, flags=flags[0], features=features, language=language)
            items = tuple(
                (item.ft_object, _face(item.ft_object), item.glyph_index, item.x, item.y) for item in laid
            )
            # the key keeps a copy of the properties: a later change to `prop` cannot alter a stored key
            _LAYOUTS[_room(_LAYOUTS, (s, prop.copy(), *key[2:]))] = items
        return items


def _font_height_metrics(prop: FontProperties, dpi: float) -> tuple[float | None, ...]:
    """(min ascent, min descent, line gap) in pixels from the font's OS/2 or hhea table, exactly as
    matplotlib 3.11's `Text._get_layout` computes them; Nones (matplotlib then measures "lp") without either."""
    font: Any = get_font(fontManager._find_fonts_by_props(prop))
    for table_name, gap_key, ascent_key, descent_key in (
        ("OS/2", "sTypoLineGap", "sTypoAscender", "sTypoDescender"),
        ("hhea", "lineGap", "ascent", "descent"),
    ):
        table = font.get_sfnt_table(table_name)
        if table is None:
            continue
        scale = 1 / font.get_sfnt_table("head")["unitsPerEm"] * prop.get_size_in_points() * dpi / 72
        return table[ascent_key] * scale, -table[descent_key] * scale, table[gap_key] * scale
    return None, None, None


def _face(font: Any) -> tuple[str, str]:
    """What identifies a font's glyphs: its file and face (and not the object, which is per thread)."""
    return str(font.fname), str(font.postscript_name)


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
) -> tuple[np.ndarray, int, int]:
    """One glyph rendered at the sub-pixel offset (rx, ry) as RendererAgg renders it: (coverage bitmap,
    left, top in pixels relative to the whole-pixel pen position)."""
    font.set_size(size, dpi)
    matrix = (0x10000 * np.array([[cos, -sin], [sin, cos]])).round().astype(int)
    font._set_transform(matrix, [rx, ry])
    bitmap = font._render_glyph(
        glyph_index, flags[0], RENDER_MODE.NORMAL if antialiased else RENDER_MODE.MONO
    )
    buffer = np.array(bitmap.buffer)  # a copy: the glyph slot is reused by the next render
    if not antialiased:
        buffer *= 0xFF
    return buffer, int(bitmap.left), int(bitmap.top)


def _room(cache: dict[Any, Any], key: Any) -> Any:
    """`key`, after emptying `cache` if it is full (a bound on memory; entries are cheap to redo)."""
    if len(cache) >= MAX_ENTRIES:
        cache.clear()
    return key


_TEXT: Any = Text  # its private `_get_layout` is replaced (`_use_text_layout_cache`)
_STOCK_GET_LAYOUT = _TEXT._get_layout


def _text_layout_key(text: Any, renderer: CachedTextRenderer) -> tuple[Any, ...] | None:
    """What `Text._get_layout` reads, or None for text it lays out from more (wrapped text depends on its
    position, TeX and mathtext on their own settings): the string, font, figure and renderer dpi, rotation,
    alignments, line spacing, and the hinting and kerning settings the measured sizes depend on."""
    s = text.get_text()
    if text.get_wrap() or text.get_usetex() or (text.get_parse_math() and "$" in s):
        return None
    rc = mpl.rcParams._get  # the values as set (no deprecation or backend lookup), read quickly
    return (
        s,
        text.get_fontproperties(),
        text.get_figure(root=True).dpi,
        renderer.dpi,
        text.get_rotation(),
        text.get_rotation_mode(),
        text.get_horizontalalignment(),
        text.get_verticalalignment(),
        text._get_multialignment(),
        text._linespacing,
        _hinting_flag(),
        rc("text.hinting_factor"),
        rc("text.kerning_factor"),
    )


_HINTING_FLAGS: dict[object, Any] = {}


def _hinting_flag() -> Any:
    """`backend_agg.get_hinting_flag()` (FreeType's load flags for rcParams["text.hinting"]), kept per
    value of that setting: it builds its mapping at every call, several times per label drawn."""
    setting = mpl.rcParams._get("text.hinting")
    flag = _HINTING_FLAGS.get(setting)
    if flag is None:
        flag = _HINTING_FLAGS[setting] = backend_agg.get_hinting_flag()
    return flag


def _cached_text_layout(text: Any, renderer: Any) -> Any:
    """`Text._get_layout`, kept per `_text_layout_key` for text measured or drawn by a
    `CachedTextRenderer` (any other renderer: matplotlib's own)."""
    key = _text_layout_key(text, renderer) if isinstance(renderer, CachedTextRenderer) else None
    if key is None:
        return _STOCK_GET_LAYOUT(text, renderer)
    layout = _TEXT_LAYOUTS.get(key)
    if layout is None:
        bbox, lines, corner = _STOCK_GET_LAYOUT(text, renderer)
        layout = (bbox.get_points().copy(), lines, corner)
        # the key keeps a copy of the properties: a later change to the text's cannot alter a stored key
        _TEXT_LAYOUTS[_room(_TEXT_LAYOUTS, (key[0], key[1].copy(), *key[2:]))] = layout
    points, lines, corner = layout
    return Bbox(points.copy()), list(lines), corner  # fresh: a caller may change what it is given


def _use_text_layout_cache() -> None:
    """Route `Text._get_layout` through `_cached_text_layout` (once; matplotlib's own for other renderers)."""
    if SUPPORTED and _TEXT._get_layout is _STOCK_GET_LAYOUT:
        _TEXT._get_layout = _cached_text_layout


class CachedTextCanvas(FigureCanvasAgg):
    """A `FigureCanvasAgg` drawing with `CachedTextRenderer`."""

    def __init__(self, figure: Any = None) -> None:
        super().__init__(figure)
        _use_text_layout_cache()

    def get_renderer(self) -> RendererAgg:
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = CachedTextRenderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer
