"""The figures' fast paths draw what matplotlib draws: cached text gives the same pixels as RendererAgg,
and the PNG encoder is lossless (decoded pixels equal the rendered ones)."""

from __future__ import annotations

import base64
import io
import multiprocessing
import os
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from protocol_runner.report import glyph_cache
from protocol_runner.report.canvas import DPI, LAYOUTS, canvas_axes, to_data_uri
from protocol_runner.report.figures import bouc_wen_figure, hysteresis_figure, time_series_figure
from protocol_runner.report.load import load_report_data
from protocol_runner.report.png import png_bytes


def _decoded(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def _uri_pixels(uri: str) -> np.ndarray:
    return _decoded(base64.b64decode(uri.split(",", 1)[1]))


def _stock_pixels(fig: Figure) -> np.ndarray:
    """`fig` drawn by matplotlib's own Agg canvas (the canvas is put back afterwards)."""
    own = fig.canvas
    stock = FigureCanvasAgg(fig)
    stock.draw()
    pixels = np.asarray(stock.buffer_rgba()).copy()
    fig.set_canvas(own)
    return pixels


@pytest.mark.skipif(not glyph_cache.SUPPORTED, reason="matplotlib without per-glyph FreeType calls")
@pytest.mark.parametrize("figure", [hysteresis_figure, time_series_figure, bouc_wen_figure])
def test_cached_text_draws_the_pixels_matplotlib_draws(small_archive: Path, figure: object) -> None:
    data = load_report_data(small_archive)
    kind = "single" if figure is hysteresis_figure else "double"
    for cfg in data.configurations[:3]:  # three figures in a row: the second and third draw from the cache
        uri = figure(cfg)  # type: ignore[operator]
        fig, _ = canvas_axes(kind)  # the canvas just drawn, reset: draw the same figure again, stock
        figure(cfg)  # type: ignore[operator]
        assert np.array_equal(_uri_pixels(uri), _stock_pixels(fig))
    assert glyph_cache._GLYPHS, "the glyphs were not drawn through the cache"


@pytest.mark.skipif(not glyph_cache.SUPPORTED, reason="matplotlib without per-glyph FreeType calls")
def test_rotated_text_at_every_sub_pixel_offset_matches_matplotlib() -> None:
    width, height, _ = LAYOUTS["single"]
    for i in range(12):
        fig = Figure(figsize=(width, height), dpi=DPI)
        glyph_cache.CachedTextCanvas(fig)
        for j, angle in enumerate((0.0, 90.0, 33.0)):
            x = 0.1 + 0.3 * j + i / (64.0 * width * DPI)  # the pen moves by 1/64 px from figure to figure
            fig.text(x, 0.2 + 0.017 * i, f"Torque (N·m) {i}", rotation=angle, fontsize=7 + j)
        fig.canvas.draw()
        cached = np.asarray(fig.canvas.buffer_rgba()).copy()
        assert np.array_equal(cached, _stock_pixels(fig))


def test_png_is_lossless_and_drops_only_an_opaque_alpha() -> None:
    rng = np.random.default_rng(3)
    opaque = rng.integers(0, 256, size=(37, 51, 4), dtype=np.uint8)
    opaque[..., 3] = 255
    png = png_bytes(opaque, DPI)
    image = Image.open(io.BytesIO(png))
    assert image.mode == "RGB" and image.size == (51, 37)
    assert image.info["dpi"] == pytest.approx((DPI, DPI), abs=0.01)
    assert np.array_equal(_decoded(png), opaque)
    translucent = opaque.copy()
    translucent[5, 7, 3] = 128
    image = Image.open(io.BytesIO(png_bytes(translucent, DPI)))
    assert image.mode == "RGBA"
    assert np.array_equal(np.asarray(image), translucent)


def test_report_figure_png_holds_the_rendered_pixels(small_archive: Path) -> None:
    cfg = load_report_data(small_archive).configurations[0]
    uri = hysteresis_figure(cfg)
    fig, _ = canvas_axes("single")
    hysteresis_figure(cfg)
    # what matplotlib's own PNG writer stores for the same figure
    stock = io.BytesIO()
    fig.savefig(stock, format="png", dpi=DPI)
    assert np.array_equal(_uri_pixels(uri), _decoded(stock.getvalue()))
    assert to_data_uri(fig) == uri  # the same pixels give the same bytes


def _cache_sizes(_: int) -> tuple[int, int]:
    return len(glyph_cache._LAYOUTS), len(glyph_cache._GLYPHS)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_forked_child_lays_text_out_with_its_own_fonts(small_archive: Path) -> None:
    """A FreeType face read by two processes through the file they inherited fails ("invalid outline"):
    a forked child forgets the laid-out strings (they hold the parent's font objects) and keeps the glyph
    rasters, which are plain arrays."""
    hysteresis_figure(load_report_data(small_archive).configurations[0])
    assert glyph_cache._LAYOUTS and glyph_cache._GLYPHS
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(2) as pool:
        sizes = pool.map(_cache_sizes, [0, 1])
    assert all(layouts == 0 and glyphs == len(glyph_cache._GLYPHS) for layouts, glyphs in sizes)


@pytest.mark.parametrize("family", ["DejaVu Sans", "DejaVu Serif"])
def test_cached_font_heights_lay_text_out_as_matplotlib_does(family: str) -> None:
    """`Text._get_layout` takes the font's ascent, descent and line gap from the cached renderer: the text
    boxes (what places every label) are those matplotlib computes from the font tables itself."""
    width, height, _ = LAYOUTS["single"]
    for size in (6.5, 7.0, 8.5, 11.0):
        fig = Figure(figsize=(width, height), dpi=DPI)
        glyph_cache.CachedTextCanvas(fig)
        cached_renderer = fig.canvas.get_renderer()
        stock_renderer = FigureCanvasAgg(Figure(figsize=(width, height), dpi=DPI)).get_renderer()
        assert not hasattr(stock_renderer, "_get_font_height_metrics")
        for text in ("Torque (N·m)", "two\nlines", "-0.5"):
            artist = fig.text(0.3, 0.4, text, fontsize=size, family=family, rotation=33.0)
            cached = artist._get_layout(cached_renderer)
            stock = artist._get_layout(stock_renderer)
            assert np.array_equal(cached[0].bounds, stock[0].bounds)
            assert cached[1:] == stock[1:]


def _tick_state(ax: object) -> list[tuple[object, ...]]:
    return [
        (
            t.gridline.get_visible(),
            t.gridline.get_linewidth(),
            t.gridline.get_alpha(),
            t.label1.get_fontsize(),
        )
        for axis in (ax.xaxis, ax.yaxis)  # type: ignore[attr-defined]
        for t in axis.get_major_ticks()
    ]


@pytest.mark.parametrize(
    "change",
    [
        lambda ax: ax.tick_params(axis="x", labelsize=5, grid_alpha=0.9),  # the axis' tick parameters
        lambda ax: ax.set_xticks([0.0, 1.0], ["a", "b"], fontsize=5.5),  # only the existing labels
        lambda ax: ax.yaxis.get_major_ticks()[0].gridline.set_linewidth(2.0),  # one grid line
    ],
)
def test_style_on_a_reused_canvas_restores_a_changed_tick_style(change: object) -> None:
    """`style` skips re-applying the grid and tick size when a reused canvas has them already, and applies
    them when a figure changed them, also on single ticks (the energy bars' labels are set at 5.5 pt, and
    `style` has always drawn them at 7 pt)."""
    from protocol_runner.report.canvas import style

    _, (ax,) = canvas_axes("single")
    style(ax, "x", "y")
    change(ax)  # type: ignore[operator]
    _, (ax,) = canvas_axes("single")
    style(ax, "x", "y")
    fresh = Figure().add_subplot()
    fresh.set_xticks([0.0, 1.0], ["a", "b"])
    style(fresh, "x", "y")
    assert ax.xaxis.get_tick_params() == fresh.xaxis.get_tick_params()
    assert ax.yaxis.get_tick_params() == fresh.yaxis.get_tick_params()
    assert {state for state in _tick_state(ax)} == {(True, 0.4, 0.5, 7.0)}
