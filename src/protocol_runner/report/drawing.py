"""The figures' drawing kit: a new matplotlib `Figure` per figure (Agg, no pyplot state) in one of the
report's layouts, the common labels, colours, styling and colour key (outside the data area), and the PNG
data URI every figure function returns (matplotlib's own PNG writer)."""

from __future__ import annotations

import base64
import io
import math
import textwrap
from typing import Any

from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

DPI = 100  # a figure's pixels per inch: its text as legible on a laptop's screen as the page's own text
ANGLE_LABEL = "Angle (deg)"
TORQUE_LABEL = "Torque (N·m)"
TIME_LABEL = "Time (s)"
ENERGY_LABEL = "Energy per cycle (J)"
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")

LAYOUTS: dict[str, tuple[float, float, tuple[tuple[float, float, float, float], ...]]] = {
    "single": (5.6, 3.3, ((0.11, 0.14, 0.6, 0.76),)),
    "bars": (4.6, 3.0, ((0.14, 0.2, 0.82, 0.68),)),
    "double": (7.6, 3.3, ((0.075, 0.14, 0.33, 0.76), (0.5, 0.14, 0.33, 0.76))),
}
"""Each kind of figure: width and height in inches, and its axes' rectangles (left, bottom, width, height,
as fractions of the figure). "single" and "double" leave the figure's right part to the colour key
(`legend`), outside the data; "bars" has none."""


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


def style(ax: Axes, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Axis labels, a small title just above the axes, a light grid and small tick labels."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title or "", fontsize=8.5, y=1.01)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    ax.tick_params(labelsize=7.0)


def empty(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=8, color="#666666")


KEY_SIZE = 7.5  # points: the tick labels' size and a little more
KEY_GAP = 0.015  # between the rightmost axes and the key, as a fraction of the figure's width
KEY_CHAR_EM = 0.6  # a wide character of the key's font, in ems: the wrapping's conservative measure


def legend(ax: Axes) -> None:
    """The colour key of `ax`'s labelled artists, right of the figure's rightmost axes (outside the data,
    where the layouts leave room), top-aligned with them: always at the same place, so figures read alike,
    and never over a line (loc="best" inside the axes moves from figure to figure and can hide data). In a
    two-panel figure it is the key of both panels, which draw the same series in the same colours."""
    handles, labels = ax.get_legend_handles_labels()
    _key(ax.get_figure(), handles, labels)


def grid_legend(axes: list[Axes]) -> None:
    """`legend` of a grid of panels (`new_grid`): the key of every panel's labelled artists, each label
    once (the panels draw the same series in the same colours; a series some panels lack, such as a fit
    only some joints have, is still in it)."""
    seen: dict[str, Any] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            seen.setdefault(label, handle)
    if axes:
        _key(axes[0].get_figure(), list(seen.values()), list(seen))


def _key(fig: object, handles: list[Any], labels: list[str]) -> None:
    if not handles:
        return
    assert isinstance(fig, Figure)
    boxes = [a.get_position() for a in fig.axes]
    right, top = max(b.x1 for b in boxes), max(b.y1 for b in boxes)
    # long labels (a comparison's "level (value), RMSE ...") wrapped to the room the layout leaves
    room_pt = (1.0 - right - KEY_GAP) * fig.get_figwidth() * 72.0 - (1.6 + 0.8) * KEY_SIZE  # less the handle
    columns = max(8, int(room_pt / (KEY_CHAR_EM * KEY_SIZE)))
    fig.legend(
        handles,
        [textwrap.fill(label, columns) for label in labels],
        loc="upper left",
        bbox_to_anchor=(right + KEY_GAP, top),
        bbox_transform=fig.transFigure,
        borderaxespad=0.0,
        frameon=False,
        fontsize=KEY_SIZE,
        handlelength=1.6,
        labelspacing=0.35,
    )


PANEL_IN = (2.6, 2.2)  # one panel of a grid: width and height in inches, its labels and title included
PANEL_MARGINS_IN = (0.55, 0.45, 0.2, 0.35)  # inside a panel, around its axes: left, bottom, right, top
KEY_IN = 1.5  # right of a grid: the colour key
GRID_COLUMNS = 4  # panels per row: four joints' panels, or two joints' pairs of panels
LABEL_SIZE = 8.0  # a grid panel's axis labels (points)


def new_grid(n_panels: int, columns: int) -> tuple[Figure, list[Axes]]:
    """A new figure of `n_panels` small panels (one joint's each, or two per joint), `columns` per row and
    rows as many as needed, in reading order, with room for the colour key at the right (`grid_legend`):
    small multiples, each panel as legible at twelve joints as at two."""
    columns = max(1, min(columns, n_panels))
    rows = max(1, math.ceil(n_panels / columns))
    panel_w, panel_h = PANEL_IN
    left, bottom, right, top = PANEL_MARGINS_IN
    width_in, height_in = columns * panel_w + KEY_IN, rows * panel_h
    fig = Figure(figsize=(width_in, height_in), dpi=DPI)
    axes = []
    for k in range(n_panels):
        row, column = divmod(k, columns)
        rect = (
            (column * panel_w + left) / width_in,
            ((rows - 1 - row) * panel_h + bottom) / height_in,
            (panel_w - left - right) / width_in,
            (panel_h - bottom - top) / height_in,
        )
        ax = fig.add_axes(rect)
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
        axes.append(ax)
    return fig, axes


def panel_style(ax: Axes, xlabel: str, ylabel: str, title: str) -> None:
    """`style` for a grid panel: the same, with axis labels sized to the panel."""
    style(ax, xlabel, ylabel, title)
    ax.xaxis.label.set_fontsize(LABEL_SIZE)
    ax.yaxis.label.set_fontsize(LABEL_SIZE)


def finish(fig: Figure, ax: Axes, xlabel: str, ylabel: str, title: str) -> str:
    """How a single-panel figure ends: `ax` labelled (`style`), its colour key drawn (`legend`), `fig`
    rendered to a data URI."""
    style(ax, xlabel, ylabel, title)
    legend(ax)
    return to_data_uri(fig)
