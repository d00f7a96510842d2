"""The figures' drawing kit: reusable Agg canvases (no pyplot state), the common labels, colours, styling
and legends, and the PNG data URI every figure function returns."""

from __future__ import annotations

import base64
import functools
import io
from collections.abc import Sequence
from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.container import Container
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator, ScalarFormatter

from protocol_runner.report.glyph_cache import CachedTextCanvas
from protocol_runner.report.png import png_bytes

DPI = 80
ANGLE_LABEL = "Angle (deg)"
TORQUE_LABEL = "Torque (N·m)"
TIME_LABEL = "Time (s)"
ENERGY_LABEL = "Energy per cycle (J)"
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


# ----------------------------------------------------------------------------------------- drawing kit


class Canvas:
    """One Figure of a given kind, reused for every figure of that kind (its axes and ticks persist).

    Matplotlib spends most of a small figure's time creating tick and text objects; clearing only the
    plotted artists between uses keeps them (the report draws several figures per configuration).
    Not thread-safe: each process draws one figure at a time.
    """

    def __init__(self, width_in: float, height_in: float, rects: Sequence[tuple[float, float, float, float]]):
        self.fig = Figure(figsize=(width_in, height_in), dpi=DPI)
        CachedTextCanvas(self.fig)  # text drawn from cached layouts and glyphs (glyph_cache.py)
        self.axes = [self.fig.add_axes(rect) for rect in rects]
        for ax in self.axes:
            # fixed label positions: matplotlib otherwise measures every tick label to place them
            ax.xaxis.set_label_coords(0.5, -0.11)
            ax.yaxis.set_label_coords(-0.11 if len(rects) == 1 else -0.17, 0.5)
            TickLabelBoxes(ax.xaxis)
            TickLabelBoxes(ax.yaxis)

    def reset(self) -> list[Axes]:
        for ax in self.axes:
            for artist in [*ax.lines, *ax.patches, *ax.collections, *ax.texts]:
                artist.remove()
            legend = ax.get_legend()
            if legend is not None:
                legend.remove()
            ax.containers.clear()
            ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
            ax.xaxis.set_major_formatter(ScalarFormatter())
            ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
            ax.set_autoscale_on(True)
            ax.relim()
        return self.axes


class TickLabelBoxes:
    """An axis drawn as `Axis.draw` draws it, with two costs of small figures left out, the pixels the same.

    - Tick label boxes: `Axis.draw` measures every tick label (a text layout and a round trip of the
      figure's dpi each) to place the axis label, which `Canvas` places itself, and the offset text ("1e4",
      "+2.5e2"), which is drawn only when the formatter has an offset. Without either, the boxes are not
      asked for; anything else that asks (a tight bounding box) measures as matplotlib does.
    - One draw per tick line: the ticks' grid lines are drawn as one line of several pieces, and their
      tick marks as one line of several markers (`LineBatch`), where they look alike (they do unless a
      tick was styled on its own); then the tick labels, one by one. Each tick's pieces are far apart, so
      drawing all grid lines before the tick marks and labels paints the same pixels
      (tests/report/test_canvas_batched_ticks.py compares them with matplotlib's own drawing).
    """

    def __init__(self, axis: Any) -> None:  # an `Axis`: its draw and private `_get_ticklabel_bboxes` replaced
        self.axis = axis
        self.drawing = False
        self.batches = {name: LineBatch() for name in TICK_LINES}
        axis.draw = self.draw
        axis._get_ticklabel_bboxes = self.boxes

    def draw(self, renderer: Any) -> None:
        axis = self.axis
        if not axis.get_visible():
            return
        self.drawing = True
        try:
            if not BATCHED_TICKS:  # a matplotlib whose `Axis.draw` this copy was not checked against
                type(axis).draw(axis, renderer)
                return
            # `Axis.draw` (matplotlib 3.8-3.11), with the ticks' lines drawn by kind (`LineBatch`)
            renderer.open_group(AXIS_GROUP, gid=axis.get_gid())
            ticks = axis._update_ticks()
            boxes1, boxes2 = axis._get_ticklabel_bboxes(ticks, renderer)
            shown = [tick for tick in ticks if tick.get_visible()]
            for name in TICK_LINES:
                self.batches[name].draw([getattr(tick, name) for tick in shown], renderer)
            for tick in ticks:
                if tick.get_visible():
                    tick.label1.draw(renderer)
                    tick.label2.draw(renderer)
                tick.stale = False
            axis._update_label_position(renderer)
            axis.label.draw(renderer)
            axis._update_offset_text_position(boxes1, boxes2)
            axis.offsetText.set_text(axis.major.formatter.get_offset())
            axis.offsetText.draw(renderer)
            renderer.close_group(AXIS_GROUP)
            axis.stale = False
        finally:
            self.drawing = False

    def boxes(self, ticks: list[Any], renderer: Any) -> Any:
        axis = self.axis
        if self.drawing and not (axis._autolabelpos or axis.major.formatter.get_offset()):
            return [], []
        return type(axis)._get_ticklabel_bboxes(axis, ticks, renderer)


BATCHED_TICKS = tuple(int(part) for part in matplotlib.__version__.split(".")[:2]) < (3, 12)
"""`TickLabelBoxes.draw` follows `Axis.draw` of matplotlib 3.8-3.11 (checked pixel for pixel on 3.11); a
later matplotlib draws its axes its own way until this is checked again."""
AXIS_GROUP = "matplotlib.axis"  # the group name `Axis.draw` opens (the module's __name__)
TICK_LINES = ("gridline", "tick1line", "tick2line")  # a tick's lines, in the order `Tick.draw` draws them


class LineBatch:
    """Several `Line2D`s that look alike (`_look`) drawn as one: their points joined (a line style's pieces
    separated by NaN, which the renderer treats as a pen lift; markers simply listed), so the renderer is
    called once instead of once per line. Lines that do not all look alike are drawn one by one."""

    def __init__(self) -> None:
        self.line = Line2D([], [])

    def draw(self, lines: list[Line2D], renderer: Any) -> None:
        shown = [line for line in lines if line.get_visible()]
        if (
            len(shown) < 2
            or not _joinable(shown[0])
            or any(_look(line) != _look(shown[0]) for line in shown[1:])
        ):
            for line in lines:
                line.draw(renderer)
            return
        first = shown[0]
        joined = self.line
        joined.update_from(first)  # style, transform and clipping (Artist/Line2D.update_from)
        joined.set_antialiased(first.get_antialiased())  # not copied by update_from
        joined.set_snap(first.get_snap())
        pieces = first.get_linestyle() not in _NO_LINE
        xs: list[float] = []
        ys: list[float] = []
        for line in shown:
            xs.extend(np.asarray(line.get_xdata(orig=False), dtype=np.float64).tolist())
            ys.extend(np.asarray(line.get_ydata(orig=False), dtype=np.float64).tolist())
            if pieces:
                xs.append(np.nan)
                ys.append(np.nan)
        joined.set_data(xs, ys)
        joined.draw(renderer)
        for line in lines:
            line.stale = False


_NO_LINE = ("None", "none", " ", "")


def _joinable(line: Line2D) -> bool:
    """Whether drawing `line`'s points together with others' paints what drawing each does: not with path
    effects (a shadow of the joined path), a sketch (its jitter depends on the path), an Agg filter or
    rasterisation (they work on the whole drawing), every-nth markers or a step draw style (they depend on
    the points' order)."""
    return (
        not line.get_path_effects()
        and line.get_sketch_params() is None
        and line.get_agg_filter() is None
        and not line.get_rasterized()
        and line.get_markevery() is None
        and line.get_drawstyle() == "default"
    )


def _look(line: Any) -> tuple[object, ...]:  # a Line2D: some of what it draws with has no public getter
    """What decides how `line` is drawn, but for its points (the fields `Line2D.draw` reads)."""
    return (
        line.get_transform(),
        line.clipbox,
        line._clippath,  # a TransformedPatchPath or None
        line.get_clip_on(),
        line.get_alpha(),
        line.get_antialiased(),
        line.get_snap(),
        line.get_path_effects() == [],
        line.get_sketch_params(),
        line.get_rasterized(),
        line.get_agg_filter(),
        line.get_gid(),
        line.get_url(),
        line._linestyle,
        line._dash_pattern,
        line._linewidth,
        str(line._color),
        line._gapcolor,
        line.get_drawstyle(),
        line.get_markevery(),
        line.get_marker(),
        line.get_fillstyle(),
        line._markersize,
        line._markeredgewidth,
        str(line._markeredgecolor),
        str(line._markerfacecolor),
        str(line._markerfacecoloralt),
        line._solidcapstyle,
        line._solidjoinstyle,
        line._dashcapstyle,
        line._dashjoinstyle,
    )


_CANVASES: dict[str, Canvas] = {}
LAYOUTS: dict[str, tuple[float, float, tuple[tuple[float, float, float, float], ...]]] = {
    "single": (4.6, 3.3, ((0.14, 0.14, 0.82, 0.76),)),
    "bars": (4.6, 3.0, ((0.14, 0.2, 0.82, 0.68),)),
    "double": (6.4, 3.3, ((0.10, 0.14, 0.38, 0.76), (0.60, 0.14, 0.38, 0.76))),
}


def canvas_axes(kind: str) -> tuple[Figure, list[Axes]]:
    canvas = _CANVASES.get(kind)
    if canvas is None:
        width, height, rects = LAYOUTS[kind]
        canvas = _CANVASES[kind] = Canvas(width, height, rects)
    return canvas.fig, canvas.reset()


def to_data_uri(fig: Figure) -> str:
    """Encode `fig` as a PNG data URI (deterministic: no timestamp or software tag in the PNG)."""
    if isinstance(fig.canvas, CachedTextCanvas) and fig.dpi == DPI:  # a report canvas: drawn as it is
        fig.canvas.draw()
        png = png_bytes(np.asarray(fig.canvas.buffer_rgba()), DPI)
    else:  # any other figure, at the report's resolution
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None}, pil_kwargs={"compress_level": 1})
        png = buf.getvalue()
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def style(ax: Axes, xlabel: str, ylabel: str, title: str | None = None) -> None:
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    # an explicit y skips matplotlib's costly automatic title placement
    ax.set_title(title or "", fontsize=8.5, y=1.01)
    # a reused canvas keeps its grid and tick style: applying them again re-sets every tick (a tenth of the
    # drawing time) and changes nothing, unless a figure changed them (an energy figure's smaller labels)
    if not (_styled(ax.xaxis, "x") and _styled(ax.yaxis, "y")):
        _grid_and_tick_style(ax)
    ax.autoscale_view()


GRID_LINEWIDTH = 0.4
GRID_ALPHA = 0.5
TICK_LABEL_SIZE = 7.0


def _grid_and_tick_style(ax: Axes) -> None:
    ax.grid(True, linewidth=GRID_LINEWIDTH, alpha=GRID_ALPHA)
    ax.tick_params(labelsize=TICK_LABEL_SIZE)


def _styled(axis: Axis, axis_name: str) -> bool:
    """Whether `_grid_and_tick_style` would change nothing on `axis`: its tick parameters (what new ticks
    take) are those it sets, and so is what it sets on every existing major tick (grid line shown, its
    width and alpha, the labels' size)."""
    return axis.get_tick_params() == _styled_tick_params(axis_name) and all(
        tick.gridline.get_visible()
        and tick.gridline.get_linewidth() == GRID_LINEWIDTH
        and tick.gridline.get_alpha() == GRID_ALPHA
        and tick.label1.get_fontsize() == TICK_LABEL_SIZE
        and tick.label2.get_fontsize() == TICK_LABEL_SIZE
        for tick in axis.majorTicks
    )


@functools.cache
def _styled_tick_params(axis_name: str) -> dict[str, object]:
    """The tick parameters of a default axis (of the kind `axis_name`) after `style`'s grid and tick size."""
    ax = Figure().add_subplot()
    _grid_and_tick_style(ax)
    return dict(getattr(ax, f"{axis_name}axis").get_tick_params())


def empty(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=8, color="#666666")


KEY_SIZE = 7.5  # points: the tick labels' size and a little more, legible at the page's 80 dpi
KEY_LINE = 0.075  # the key's line spacing, in axes heights


def legend(ax: Axes, *, bottom: bool = False) -> None:
    """A colour key in the top-left (or bottom-left) corner: one coloured text line per labelled artist.

    Cheaper than `Axes.legend` (whose box layout was a fifth of the report's drawing time) and
    deterministic in position (loc="best" would search the data)."""
    handles, labels = ax.get_legend_handles_labels()
    n = len(labels)
    for i, (handle, label) in enumerate(zip(handles, labels, strict=True)):
        color, glyph = swatch(handle)
        ax.text(
            0.02,
            (0.03 + KEY_LINE * (n - 1 - i)) if bottom else (0.97 - KEY_LINE * i),
            f"{glyph} {label}",
            color=color,
            transform=ax.transAxes,
            fontsize=KEY_SIZE,
            ha="left",
            va="bottom" if bottom else "top",
        )


def finish(fig: Figure, ax: Axes, xlabel: str, ylabel: str, title: str, *, bottom: bool = False) -> str:
    """How a single-panel figure ends: `ax` labelled (`style`), its colour key drawn (`legend`), `fig`
    rendered to a data URI."""
    style(ax, xlabel, ylabel, title)
    legend(ax, bottom=bottom)
    return to_data_uri(fig)


def swatch(handle: object) -> tuple[object, str]:
    """Colour and a glyph standing for the artist's line style, marker or fill."""
    if isinstance(handle, Line2D):
        style = handle.get_linestyle()
        marker = handle.get_marker()
        if style in ("None", "", " ") and marker not in (None, "None", "", " "):
            return handle.get_color(), "●"
        glyph = {"--": "- -", ":": "···", "-.": "-·-"}.get(str(style), "—")
        return handle.get_color(), glyph
    if isinstance(handle, Patch):
        return handle.get_facecolor(), "■"
    if isinstance(handle, Container) and len(handle) and isinstance(handle[0], Patch):
        return handle[0].get_facecolor(), "■"
    return "k", "—"
