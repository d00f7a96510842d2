"""The figures' drawing kit: a new matplotlib `Figure` per figure (Agg, no pyplot state) in one of the
report's layouts, the common labels, colours, styling and colour key, and the PNG data URI every figure
function returns (matplotlib's own PNG writer)."""

from __future__ import annotations

import base64
import io

from matplotlib.axes import Axes
from matplotlib.container import Container
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

DPI = 80
ANGLE_LABEL = "Angle (deg)"
TORQUE_LABEL = "Torque (N·m)"
TIME_LABEL = "Time (s)"
ENERGY_LABEL = "Energy per cycle (J)"
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")

LAYOUTS: dict[str, tuple[float, float, tuple[tuple[float, float, float, float], ...]]] = {
    "single": (4.6, 3.3, ((0.14, 0.14, 0.82, 0.76),)),
    "bars": (4.6, 3.0, ((0.14, 0.2, 0.82, 0.68),)),
    "double": (6.4, 3.3, ((0.10, 0.14, 0.38, 0.76), (0.60, 0.14, 0.38, 0.76))),
}
"""Each kind of figure: width and height in inches, and its axes' rectangles (left, bottom, width, height,
as fractions of the figure)."""


def new_figure(kind: str) -> tuple[Figure, list[Axes]]:
    """A new figure of the layout `kind` (`LAYOUTS`) and its axes, each with at most five tick intervals."""
    width_in, height_in, rects = LAYOUTS[kind]
    fig = Figure(figsize=(width_in, height_in), dpi=DPI)
    axes = [fig.add_axes(rect) for rect in rects]
    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
    return fig, axes


def to_data_uri(fig: Figure) -> str:
    """Encode `fig` as a PNG data URI at the report's resolution (deterministic: no timestamp or software
    tag in the PNG; zlib level 1, which writes the flat plot images several times faster than the default
    level for a slightly larger file)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None}, pil_kwargs={"compress_level": 1})
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


GRID_LINEWIDTH = 0.4
GRID_ALPHA = 0.5
TICK_LABEL_SIZE = 7.0


def style(ax: Axes, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Axis labels, a small title just above the axes, a light grid and small tick labels."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title or "", fontsize=8.5, y=1.01)
    ax.grid(True, linewidth=GRID_LINEWIDTH, alpha=GRID_ALPHA)
    ax.tick_params(labelsize=TICK_LABEL_SIZE)


def empty(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=8, color="#666666")


KEY_SIZE = 7.5  # points: the tick labels' size and a little more, legible at the page's 80 dpi
KEY_LINE = 0.075  # the key's line spacing, in axes heights


def legend(ax: Axes, *, bottom: bool = False) -> None:
    """A colour key in the top-left (or bottom-left) corner: one coloured text line per labelled artist.

    Always at the same place (loc="best" would move it from figure to figure) and without a box over the
    data."""
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
        line_style = handle.get_linestyle()
        marker = handle.get_marker()
        if line_style in ("None", "", " ") and marker not in (None, "None", "", " "):
            return handle.get_color(), "●"
        glyph = {"--": "- -", ":": "···", "-.": "-·-"}.get(str(line_style), "—")
        return handle.get_color(), glyph
    if isinstance(handle, Patch):
        return handle.get_facecolor(), "■"
    if isinstance(handle, Container) and len(handle) and isinstance(handle[0], Patch):
        return handle[0].get_facecolor(), "■"
    return "k", "—"
