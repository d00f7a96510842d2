"""What the figures keep from one draw to the next never goes stale: a text laid out again after its
string, font, alignment or rotation changed on a reused canvas, an axis that skips measuring its tick labels
measures them when an offset text needs them, and each is drawn with the pixels matplotlib's own Agg
canvas draws for the same figure."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from protocol_runner.report import glyph_cache
from protocol_runner.report.canvas import DPI, LAYOUTS, Canvas, canvas_axes, style, to_data_uri
from protocol_runner.report.png import png_bytes

from .test_figure_encoding import _stock_pixels  # matplotlib's own Agg drawing of a figure

pytestmark = pytest.mark.skipif(
    not glyph_cache.SUPPORTED, reason="matplotlib without per-glyph FreeType calls"
)


def _cached_pixels(fig: Figure) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba()).copy()  # type: ignore[attr-defined]


# each change alters one thing the layout of a text depends on; the text is drawn before and after it
CHANGES: dict[str, Callable[[Text], None]] = {
    "string": lambda t: t.set_text("a much longer title, Wg (N·m)"),
    "font size": lambda t: t.set_fontsize(11.0),
    "font weight": lambda t: t.set_fontweight("bold"),
    "family": lambda t: t.set_family("DejaVu Serif"),
    "horizontal alignment": lambda t: t.set_horizontalalignment("right"),
    "vertical alignment": lambda t: t.set_verticalalignment("top"),
    "rotation": lambda t: t.set_rotation(33.0),
    "rotation mode": lambda t: (t.set_rotation(33.0), t.set_rotation_mode("anchor")),
    "line spacing": lambda t: t.set_linespacing(2.5),
    "multi-alignment": lambda t: t.set_multialignment("right"),
}


@pytest.mark.parametrize("change", list(CHANGES), ids=list(CHANGES))
def test_a_changed_text_on_a_reused_canvas_is_laid_out_anew(change: str) -> None:
    width, height, _ = LAYOUTS["single"]
    fig = Figure(figsize=(width, height), dpi=DPI)
    glyph_cache.CachedTextCanvas(fig)
    text = fig.text(0.5, 0.5, "Short\nand longer", ha="center", va="baseline", ma="left", fontsize=8.5)
    before = _cached_pixels(fig)  # laid out and kept
    assert np.array_equal(before, _stock_pixels(fig))
    CHANGES[change](text)
    after = _cached_pixels(fig)
    assert not np.array_equal(after, before), "the change should show"
    assert np.array_equal(after, _stock_pixels(fig))  # the new layout, not the one kept before


def test_a_tick_label_size_change_between_figures_moves_the_labels_as_matplotlib_does() -> None:
    """The energy bars draw their tick labels smaller: on the reused canvas the next figure's labels (the
    same strings) are laid out again at their own size, centred and placed with their own extent."""
    fig, (ax,) = canvas_axes("single")
    ax.plot([0.0, 10.0], [0.0, 5.0])
    style(ax, "x", "y", "small labels")
    ax.tick_params(labelsize=5.0)
    small = _cached_pixels(fig)
    assert np.array_equal(small, _stock_pixels(fig))
    fig, (ax,) = canvas_axes("single")
    ax.plot([0.0, 10.0], [0.0, 5.0])
    style(ax, "x", "y", "small labels")  # the same strings back at 7 pt
    assert ax.xaxis.get_major_ticks()[0].label1.get_fontsize() == 7.0
    normal = _cached_pixels(fig)
    assert not np.array_equal(normal, small)
    assert np.array_equal(normal, _stock_pixels(fig))


def test_a_kept_layout_is_matplotlibs_and_a_caller_cannot_alter_it() -> None:
    fig = Figure(figsize=(4.0, 3.0), dpi=DPI)
    glyph_cache.CachedTextCanvas(fig)
    renderer = fig.canvas.get_renderer()
    text = fig.text(0.3, 0.4, "Torque (N·m)\n−0.5", fontsize=7.0, rotation=33.0, ha="right")
    stock = text._get_layout(RendererAgg(100, 100, DPI))  # another renderer: matplotlib's own layout
    first = text._get_layout(renderer)
    first[0].set_points(np.zeros((2, 2)))  # a caller changing what it was given
    first[1].clear()
    again = text._get_layout(renderer)
    assert np.array_equal(again[0].get_points(), stock[0].get_points())
    assert again[1:] == stock[1:]


def _offset_figure(ax: object, offset: bool) -> None:
    base = 1.0e5 if offset else 0.0  # around 1e5 with a small range: ScalarFormatter draws "+1e5"
    ax.plot([base, base + 1.0, base + 2.0], [base + 1.0, base + 3.0, base + 2.0])  # type: ignore[attr-defined]
    style(ax, "x", "y", "offset" if offset else "plain")  # type: ignore[arg-type]


def _stock_canvas(kind: str) -> Canvas:
    """A new report canvas with matplotlib's own axes (no `TickLabelBoxes`) and Agg canvas (no text
    cache). (Compare it with a canvas of the same history: data near 1e5 are drawn a rounding apart by an
    axes whose transforms were last computed for other limits.)"""
    width, height, rects = LAYOUTS[kind]
    reference = Canvas(width, height, rects)
    FigureCanvasAgg(reference.fig)
    for ax in reference.axes:
        for axis in (ax.xaxis, ax.yaxis):
            del axis.draw, axis._get_ticklabel_bboxes  # back to the class's methods
    return reference


@pytest.mark.parametrize("order", [(False, True, False), (True, False, True)])
def test_an_offset_text_is_placed_from_the_tick_labels_it_sits_by(order: tuple[bool, ...]) -> None:
    """The axis measures its tick labels while drawing only when an offset text is drawn: the offset text
    is placed below the x tick labels' boxes (the y axis' beside the axes' top), figure after figure on the
    same canvas, where matplotlib's own axes place it."""
    width, height, rects = LAYOUTS["single"]
    canvas, reference = Canvas(width, height, rects), _stock_canvas("single")  # the same history
    for offset in order:
        (ax,) = canvas.reset()
        _offset_figure(ax, offset)
        pixels = _cached_pixels(canvas.fig)
        assert bool(ax.xaxis.major.formatter.get_offset()) is offset
        assert bool(ax.yaxis.major.formatter.get_offset()) is offset
        (ref_ax,) = reference.reset()
        _offset_figure(ref_ax, offset)
        reference.fig.canvas.draw()
        assert np.array_equal(pixels, np.asarray(reference.fig.canvas.buffer_rgba()))


def test_wrapped_text_is_wrapped_where_it_is_drawn() -> None:
    """Wrapped text breaks its lines by the room left to the figure's edge: moved, it is laid out anew."""
    fig = Figure(figsize=(4.0, 3.0), dpi=DPI)
    glyph_cache.CachedTextCanvas(fig)
    text = fig.text(0.05, 0.5, "a long sentence that wraps where it has little room left", wrap=True)
    drawn = []
    for x in (0.05, 0.6, 0.3, 0.6):
        text.set_x(x)
        drawn.append(_cached_pixels(fig))
        assert np.array_equal(drawn[-1], _stock_pixels(fig))
    assert not np.array_equal(drawn[1], drawn[2])


def test_a_tight_bounding_box_still_measures_the_tick_labels() -> None:
    """Outside drawing, the axis measures its tick labels as matplotlib does (a tight layout needs them)."""
    fig, (ax,) = canvas_axes("single")
    _offset_figure(ax, False)
    to_data_uri(fig)
    reference = _stock_canvas("single")
    (ref_ax,) = reference.reset()
    _offset_figure(ref_ax, False)
    reference.fig.canvas.draw()
    renderer, ref_renderer = fig.canvas.get_renderer(), reference.fig.canvas.get_renderer()
    for axis, ref_axis in ((ax.xaxis, ref_ax.xaxis), (ax.yaxis, ref_ax.yaxis)):
        boxes = axis._get_ticklabel_bboxes(axis.get_major_ticks(), renderer)
        assert boxes[0], "no tick label measured"
        assert [b.bounds for b in boxes[0]] == [
            b.bounds for b in ref_axis._get_ticklabel_bboxes(ref_axis.get_major_ticks(), ref_renderer)[0]
        ]
        assert axis.get_tightbbox(renderer).bounds == ref_axis.get_tightbbox(ref_renderer).bounds


def test_png_of_a_strided_or_translucent_image_is_lossless() -> None:
    rng = np.random.default_rng(11)
    wide = rng.integers(0, 256, size=(9, 26, 4), dtype=np.uint8)
    wide[..., 3] = 255
    strided = wide[:, ::2]  # not contiguous: alpha read per pixel
    assert png_bytes(strided, DPI) == png_bytes(np.ascontiguousarray(strided), DPI)
    almost = np.ascontiguousarray(strided)
    almost[4, 6, 3] = 254  # one pixel not opaque: RGBA
    assert png_bytes(almost, DPI)[25] == 6  # IHDR colour type: truecolour with alpha
    assert png_bytes(np.ascontiguousarray(strided), DPI)[25] == 2  # truecolour
