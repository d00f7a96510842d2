"""The report's figures: the colour key stands outside the data area, whole inside the figure, and the
figures are drawn at a resolution legible on a laptop's screen (at least 100 pixels per inch)."""

from __future__ import annotations

import base64
import struct

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from protocol_runner.report.figures import (
    ANGLE_LABEL,
    COLORS,
    TIME_LABEL,
    TORQUE_LABEL,
    legend,
    new_figure,
    style,
    to_data_uri,
)


def _angle_vs_time(kind: str, labels: tuple[str, ...]) -> Figure:
    """A typical figure of the report: step responses or a trial's angle against time, one line per label
    (and in a two-panel figure the torque beside it), with its key."""
    fig, axes = new_figure(kind)
    t_s = np.linspace(0.0, 20.0, 2000)
    for i, label in enumerate(labels):
        angle_deg = 65.0 + 45.0 * np.sin(2 * np.pi * t_s / 10.0 + i)
        axes[0].plot(t_s, angle_deg, lw=0.7, color=COLORS[i % len(COLORS)], label=label)
        if len(axes) > 1:
            axes[1].plot(t_s, 8.0 * np.cos(2 * np.pi * t_s / 10.0 + i), lw=0.7, color=COLORS[i % len(COLORS)])
    style(axes[0], TIME_LABEL, ANGLE_LABEL, "Angle, trial 1")
    if len(axes) > 1:
        style(axes[1], TIME_LABEL, TORQUE_LABEL, "Joint torque, trial 1")
    legend(axes[0])
    FigureCanvasAgg(fig).draw()  # lays the text out as the PNG writer does
    return fig


def _overlap(a: Bbox, b: Bbox) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


@pytest.mark.parametrize(
    ("kind", "labels"),
    [
        ("single", ("before: pass", "after: pass")),
        ("single", ("trial 1", "trial 2", "trial 3", "trial 4", "trial 5", "elastic model (fit)")),
        ("single", ("friction 2 (1.5 N·m), RMSE 0.23 N·m", "friction EMU (3.0 N·m), RMSE 0.31 N·m")),
        ("double", ("brace on", "brace off", "command")),
    ],
)
def test_the_colour_key_is_outside_the_data_and_inside_the_figure(kind: str, labels: tuple[str, ...]) -> None:
    fig = _angle_vs_time(kind, labels)
    (key,) = fig.legends
    canvas = fig.canvas
    assert isinstance(canvas, FigureCanvasAgg)
    renderer = canvas.get_renderer()
    key_box = key.get_window_extent(renderer)
    for ax in fig.axes:
        assert not _overlap(key_box, ax.get_window_extent(renderer)), "the key covers an axes' data area"
        for line in ax.get_lines():
            assert not _overlap(key_box, line.get_window_extent(renderer)), (
                f"the key covers {line.get_label()}"
            )
    assert [t.get_text().replace("\n", " ") for t in key.get_texts()] == list(labels)  # long ones wrapped
    figure_box = fig.bbox
    assert figure_box.x0 <= key_box.x0 and key_box.x1 <= figure_box.x1, "the key is cut off at the side"
    assert figure_box.y0 <= key_box.y0 and key_box.y1 <= figure_box.y1, (
        "the key is cut off at the top or bottom"
    )


def test_figures_are_drawn_at_100_pixels_per_inch_or_more() -> None:
    fig = _angle_vs_time("single", ("trial 1",))
    png = base64.b64decode(to_data_uri(fig).split(",", 1)[1])
    width_px, height_px = struct.unpack(">II", png[16:24])  # the PNG's IHDR chunk
    width_in, height_in = fig.get_size_inches()
    assert width_px / width_in >= 100 and height_px / height_in >= 100


def test_axes_have_a_light_grid_and_small_tick_labels_and_a_figures_own_label_size_holds() -> None:
    """Every axes of the report is made with a thin, half-transparent grid and tick labels of
    TICK_LABEL_SIZE; a tick label a figure sizes itself (a comparison's level names) keeps its size after
    the axes are styled and the figure rendered; rendering leaves the caller's matplotlib settings alone."""
    import matplotlib

    from protocol_runner.report.figures import GRID_ALPHA, GRID_LINEWIDTH, TICK_LABEL_SIZE

    before = dict(matplotlib.rcParams)
    fig, (ax,) = new_figure("bars")
    ax.bar([0, 1], [3.0, 4.0])
    ax.set_xticks([0, 1], ["a long level name", "another"], fontsize=5.5)
    style(ax, "level", "Energy per cycle (J)")
    to_data_uri(fig)
    grid = [line for line in ax.yaxis.get_gridlines() if line.get_visible()]
    assert len(grid) >= 2, "no visible grid lines"
    assert {(line.get_linewidth(), line.get_alpha()) for line in grid} == {(GRID_LINEWIDTH, GRID_ALPHA)}
    assert {t.get_fontsize() for t in ax.get_yticklabels()} == {TICK_LABEL_SIZE}
    assert {t.get_fontsize() for t in ax.get_xticklabels()} == {5.5}
    assert dict(matplotlib.rcParams) == before
