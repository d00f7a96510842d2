"""The report's axes draw their ticks' grid lines and tick marks in one renderer call per kind
(`canvas.LineBatch`), with the pixels of matplotlib's own per-tick drawing: figure after figure on a reused
canvas, with grids on and off, ticks styled alike or one on its own, and few or many ticks."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import RendererAgg

from protocol_runner.report import glyph_cache
from protocol_runner.report.canvas import BATCHED_TICKS, LAYOUTS, Canvas, style

from .test_figure_caches import _cached_pixels, _stock_canvas

pytestmark = pytest.mark.skipif(
    not glyph_cache.SUPPORTED, reason="matplotlib without per-glyph FreeType calls"
)


def _loop(axes: list[Axes]) -> None:
    angle = np.linspace(-40.0, 60.0, 400)
    for ax in axes:
        ax.plot(angle, 3.0 * np.sin(np.radians(angle)) + 0.05 * angle, color="#1f77b4")
        ax.plot(angle, 2.0 * np.cos(np.radians(angle)), "--", color="#d62728")
        style(ax, "Angle (deg)", "Torque (N·m)", "a loop")


def _bars(axes: list[Axes]) -> None:
    for ax in axes:
        ax.bar(np.arange(6), [1.5, -0.4, 2.2, 0.7, 3.1, -1.2], color="#2ca02c")
        style(ax, "configuration", "Energy per cycle (J)", "bars")
        ax.tick_params(labelsize=5.0)  # the energy figures' smaller labels


def _many_ticks(axes: list[Axes]) -> None:
    for ax in axes:
        ax.plot([0.0, 1.0e4], [-3.0e-3, 7.0e-3], marker="o")
        style(ax, "Time (s)", "Torque (N·m)", "many ticks")
        ax.xaxis.set_major_locator(__import__("matplotlib.ticker").ticker.MaxNLocator(nbins=20))


def _no_grid(axes: list[Axes]) -> None:
    for ax in axes:
        ax.plot([0.0, 5.0], [1.0, 2.0])
        style(ax, "x", "y", "no grid")
        ax.grid(False)


def _one_tick_of_its_own(axes: list[Axes]) -> None:
    """One tick restyled on its own: its axis' ticks no longer look alike and are drawn one by one."""
    for ax in axes:
        ax.plot([0.0, 5.0], [1.0, 2.0])
        style(ax, "x", "y", "one tick")
        tick = ax.xaxis.get_major_ticks()[2]
        tick.gridline.set_color("#ff7f0e")
        tick.tick1line.set_markersize(9.0)


def _sketched_grid(axes: list[Axes]) -> None:
    """Grid lines drawn with a sketch (a jitter along each path): they are not joined."""
    for ax in axes:
        ax.plot([0.0, 5.0], [1.0, 2.0])
        style(ax, "x", "y", "sketched grid")
        for tick in ax.xaxis.get_major_ticks():
            tick.gridline.set_sketch_params(1.0, 20.0, 2.0)


FIGURES: dict[str, Callable[[list[Axes]], None]] = {
    "loop": _loop,
    "bars": _bars,
    "many ticks": _many_ticks,
    "no grid": _no_grid,
    "one tick of its own": _one_tick_of_its_own,
    "sketched grid": _sketched_grid,
}


@pytest.mark.parametrize("kind", ["single", "double"])
def test_batched_ticks_paint_what_matplotlib_paints_figure_after_figure(kind: str) -> None:
    width, height, rects = LAYOUTS[kind]
    canvas, reference = Canvas(width, height, rects), _stock_canvas(kind)  # the same history
    for name in [*FIGURES, "loop", "one tick of its own", "bars", "loop"]:
        if name == "sketched grid":
            continue  # its jitter is random: compared on its own below
        FIGURES[name](canvas.reset())
        pixels = _cached_pixels(canvas.fig)
        FIGURES[name](reference.reset())
        reference.fig.canvas.draw()
        assert np.array_equal(pixels, np.asarray(reference.fig.canvas.buffer_rgba())), name


class _Counting(RendererAgg):
    """An Agg renderer that counts its path and marker calls."""

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.paths = 0
        self.markers = 0
        draw_markers = self.draw_markers  # Agg's compiled method, set on the instance

        def counted(*args: Any, **kwargs: Any) -> None:
            self.markers += 1
            draw_markers(*args, **kwargs)

        self.draw_markers = counted  # type: ignore[method-assign]

    def draw_path(self, *args: Any, **kwargs: Any) -> None:
        self.paths += 1
        super().draw_path(*args, **kwargs)


def _calls(canvas: Canvas, figure: Callable[[list[Axes]], None]) -> tuple[int, int, int, int]:
    """Path and marker calls of a drawing of `figure`, and the number of x and y ticks drawn."""
    axes = canvas.reset()
    figure(axes)
    fig = canvas.fig
    width, height = fig.canvas.get_width_height()
    renderer = _Counting(width, height, fig.dpi)
    fig.draw(renderer)
    (ax,) = axes
    return renderer.paths, renderer.markers, len(ax.xaxis._update_ticks()), len(ax.yaxis._update_ticks())


@pytest.mark.skipif(not BATCHED_TICKS, reason="a matplotlib this drawing was not checked against")
def test_the_grid_lines_and_tick_marks_of_an_axis_take_one_call_each() -> None:
    width, height, rects = LAYOUTS["single"]
    paths, markers, nx, ny = _calls(Canvas(width, height, rects), _no_grid)
    stock_paths, stock_markers, *stock_ticks = _calls(_stock_canvas("single"), _no_grid)
    assert stock_ticks == [nx, ny] and nx >= 4 and ny >= 4
    assert stock_markers - markers == nx + ny - 2  # one draw_markers per axis instead of one per tick
    assert paths == stock_paths  # no grid lines: nothing else changes
    paths, markers, nx, ny = _calls(Canvas(width, height, rects), _loop)
    stock_paths, stock_markers, *_ = _calls(_stock_canvas("single"), _loop)
    assert stock_paths - paths == nx + ny - 2  # and one draw_path for an axis' grid lines
    assert stock_markers - markers == nx + ny - 2


@pytest.mark.skipif(not BATCHED_TICKS, reason="a matplotlib this drawing was not checked against")
def test_ticks_that_do_not_look_alike_are_drawn_one_by_one() -> None:
    width, height, rects = LAYOUTS["single"]
    paths, markers, nx, ny = _calls(Canvas(width, height, rects), _one_tick_of_its_own)
    stock_paths, stock_markers, *_ = _calls(_stock_canvas("single"), _one_tick_of_its_own)
    assert nx >= 4 and ny >= 3
    # the x axis (one tick restyled) as matplotlib draws it; the y axis' lines batched
    assert stock_paths - paths == ny - 1
    assert stock_markers - markers == ny - 1


def test_lines_with_a_sketch_are_drawn_one_by_one() -> None:
    """A sketch jitters each path from a seed matplotlib draws per path: joined, the grid lines would be
    jittered as one path. They are drawn one by one, as matplotlib draws them (the call count says so;
    the pixels of a random jitter cannot be compared)."""
    width, height, rects = LAYOUTS["single"]
    paths, markers, nx, ny = _calls(Canvas(width, height, rects), _sketched_grid)
    stock_paths, stock_markers, *_ = _calls(_stock_canvas("single"), _sketched_grid)
    assert stock_paths - paths == ny - 1  # only the y axis' grid lines joined
    assert stock_markers - markers == nx + ny - 2
