"""The report's figures: matplotlib (Agg, no pyplot state) rendered to PNG data URIs.

Every figure function returns a `data:image/png;base64,...` string; angle in degrees, torque in N·m, time
in seconds, energy in joules everywhere; each names the thesis figure it follows, if any. Which figures
there are, and a comparison's labels and axes, are `figure_plan`'s (no matplotlib; nothing here knows a
factor); here each kind is drawn (`DRAW`, with the drawing kit below), here or on worker processes
(`assemble_figures`).
"""

from __future__ import annotations

import base64
import functools
import io
import math
import textwrap
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.figure_plan import (
    ComparisonAxis,
    Drawn,
    FigureSet,
    comparison_axis,
    configurations_of,
    default_workers,
    figure_ids,
    figure_jobs,
)
from protocol_runner.report.headline import ALL_JOINTS
from protocol_runner.report.model import CalibrationCheck, Configuration, ReportData, Trial
from protocol_runner.report.parallel import map_in_processes

# ----------------------------------------------------------------------------------------- drawing kit

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


GRID_LINEWIDTH = 0.4
GRID_ALPHA = 0.5
TICK_LABEL_SIZE = 7.0


def new_figure(kind: str) -> tuple[Figure, list[Axes]]:
    """A new figure of the layout `kind` (`LAYOUTS`) and its axes (`new_axes`)."""
    width_in, height_in, rects = LAYOUTS[kind]
    fig = Figure(figsize=(width_in, height_in), dpi=DPI)
    return fig, [new_axes(fig, rect, 5) for rect in rects]


def new_axes(fig: Figure, rect: tuple[float, float, float, float], nbins: int) -> Axes:
    """Axes of `fig` at `rect` with at most `nbins` tick intervals, a light grid and small tick labels, set
    before any tick is made so that each is made with them (a figure may still size its own tick labels)."""
    ax = fig.add_axes(rect)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=nbins))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=nbins))
    ax.grid(True, linewidth=GRID_LINEWIDTH, alpha=GRID_ALPHA)
    ax.tick_params(labelsize=TICK_LABEL_SIZE)
    return ax


def to_data_uri(fig: Figure) -> str:
    """Encode `fig` as a PNG data URI at the report's resolution (deterministic: no timestamp or software
    tag in the PNG; zlib level 1, which writes the flat plot images several times faster than the default
    level for a slightly larger file). Text is drawn without FreeType's hinting, as matplotlib's own image
    tests draw it: the same pixels whatever the FreeType version, and text costs less to draw."""
    buf = io.BytesIO()
    with rc_context({"text.hinting": "no_hinting"}):
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None}, pil_kwargs={"compress_level": 1})
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def style(ax: Axes, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Axis labels and a small title just above the axes (the grid and tick labels: `new_axes`)."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title or "", fontsize=8.5, y=1.01)


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
        axes.append(new_axes(fig, rect, 4))
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


# ------------------------------------------------------------------------------------ per configuration


def hysteresis_figure(cfg: Configuration) -> str:
    """Brace torque against angle, every trial (Appendix B), with the fitted elastic model if any."""
    fig, (ax,) = new_figure("single")
    _loops(ax, cfg)
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, f"Configuration {cfg.key}: brace torque vs angle")


def _loops(ax: Axes, cfg: Configuration) -> None:
    """Every processed trial's loop and the drawable elastic fit on `ax` (a note when no trial is processed)."""
    drawn = False
    for i, trial in enumerate(cfg.trials):
        if trial.processed is None:
            continue
        p = trial.processed
        ax.plot(
            p.angle_deg,
            p.brace_torque_nm,
            lw=0.7,
            color=COLORS[i % len(COLORS)],
            label=f"trial {trial.number}",
        )
        drawn = True
    fit = cfg.element_fit
    if fit is not None and fit.drawable:
        ax.plot(fit.angle_deg, fit.model_torque_nm, "k--", lw=0.9, label="elastic model (fit)")
    if not drawn:
        empty(ax, "no processed trial")


def time_series_figure(cfg: Configuration) -> str:
    """Angle and torque against time for trial 1, brace on and brace off (thesis §4.3)."""
    fig, (ax_a, ax_t) = new_figure("double")
    trial = _traces(ax_a, ax_t, cfg)
    number = trial.number if trial is not None else 1
    style(ax_a, TIME_LABEL, ANGLE_LABEL, f"Angle, trial {number}")
    style(ax_t, TIME_LABEL, TORQUE_LABEL, f"Joint torque, trial {number}")
    legend(ax_a)
    return to_data_uri(fig)


def _traces(ax_a: Axes, ax_t: Axes, cfg: Configuration) -> Trial | None:
    """The first recorded trial's angle (with the command) and torque against time, brace on and off."""
    trial = next((t for t in cfg.trials if t.brace_on is not None or t.brace_off is not None), None)
    if trial is None:
        empty(ax_a, "no trial")
        empty(ax_t, "no trial")
        return None
    for rec, name, color in (
        (trial.brace_on, "brace on", COLORS[0]),
        (trial.brace_off, "brace off", COLORS[1]),
    ):
        if rec is None:
            continue
        ax_a.plot(rec.time_s, rec.angle_deg, lw=0.6, color=color, label=name)
        ax_t.plot(rec.time_s, rec.torque_nm, lw=0.6, color=color, label=name)
    on = trial.brace_on
    if on is not None and on.command_deg.size:
        ax_a.plot(on.command_time_s, on.command_deg, ":", lw=0.8, color="k", label="command")
    return trial


def energy_cycles_figure(cfg: Configuration) -> str:
    """Energy lost per complete cycle (Eq 10-12), each trial in its colour, with the mean ± std band."""
    fig, (ax,) = new_figure("single")
    _cycles(ax, cfg, mean_label=True)
    title = f"Configuration {cfg.key}: energy lost per cycle"
    return finish(fig, ax, "Cycle (all trials in order)", ENERGY_LABEL, title)


def _cycles(ax: Axes, cfg: Configuration, *, mean_label: bool) -> None:
    """Each cycle's energy, coloured by trial, with the mean (in the key when `mean_label`) ± std band."""
    e = cfg.energy_loss_j
    if e.size == 0:
        empty(ax, "no complete cycle")
        return
    trials = cfg.energy_cycle_trial
    index = np.arange(1, e.size + 1)
    for i, number in enumerate(sorted(set(trials.tolist()))):
        sel = trials == number
        ax.plot(index[sel], e[sel], "o", ms=3.5, color=COLORS[i % len(COLORS)], label=f"trial {int(number)}")
    mean, std = cfg.energy_mean_j, cfg.energy_std_j
    ax.axhline(mean, color="k", lw=0.8, label=f"mean {mean:.2f} J" if mean_label else "mean")
    if math.isfinite(std):
        ax.axhspan(mean - std, mean + std, color="k", alpha=0.08, lw=0)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=5, integer=True))  # cycles are counted: 1, 2, 3
    top = float(np.nanmax(e)) if np.isfinite(e).any() else 1.0
    ax.set_ylim(0.0, max(top, mean + (std if math.isfinite(std) else 0.0)) * 1.15 or 1.0)


def bouc_wen_figure(cfg: Configuration) -> str:
    """Bouc-Wen model against the centred data: loop overlay (Fig 57) and torque per sample (Fig 58)."""
    fig, (ax_l, ax_s) = new_figure("double")
    _bouc_wen(ax_l, ax_s, cfg)
    style(ax_l, "Centred angle (deg)", "Centred torque (N·m)", "Hysteresis: model vs data")
    style(ax_s, "Sample (decimated)", "Centred torque (N·m)", "Torque: model vs data")
    legend(ax_l)
    return to_data_uri(fig)


def _bouc_wen(ax_l: Axes, ax_s: Axes, cfg: Configuration) -> None:
    bw = cfg.bouc_wen
    if bw is None or bw.angle_deg.size == 0:
        empty(ax_l, "no Bouc-Wen fit")
        empty(ax_s, "no Bouc-Wen fit")
        return
    ax_l.plot(bw.angle_deg, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
    ax_l.plot(bw.angle_deg, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")
    sample = np.arange(bw.torque_nm.size)
    ax_s.plot(sample, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
    ax_s.plot(sample, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")


# --------------------------------------------------------------------------------- several joints: grids


def joints_hysteresis_figure(cfgs: Sequence[Configuration]) -> str:
    """`hysteresis_figure` of each joint, one panel per joint."""
    fig, axes = new_grid(len(cfgs), GRID_COLUMNS)
    for ax, cfg in zip(axes, cfgs, strict=True):
        _loops(ax, cfg)
        panel_style(ax, ANGLE_LABEL, TORQUE_LABEL, cfg.joint)
    grid_legend(axes)
    return to_data_uri(fig)


def joints_time_figure(cfgs: Sequence[Configuration]) -> str:
    """`time_series_figure` of each joint: its angle and its torque, side by side, per joint."""
    fig, axes = new_grid(2 * len(cfgs), GRID_COLUMNS)
    for k, cfg in enumerate(cfgs):
        ax_a, ax_t = axes[2 * k], axes[2 * k + 1]
        trial = _traces(ax_a, ax_t, cfg)
        number = trial.number if trial is not None else 1
        panel_style(ax_a, TIME_LABEL, ANGLE_LABEL, f"{cfg.joint}: angle, trial {number}")
        panel_style(ax_t, TIME_LABEL, TORQUE_LABEL, f"{cfg.joint}: torque, trial {number}")
    grid_legend(axes)
    return to_data_uri(fig)


def joints_energy_figure(cfgs: Sequence[Configuration]) -> str:
    """`energy_cycles_figure` of each joint, one panel per joint, its mean in the panel's title."""
    fig, axes = new_grid(len(cfgs), GRID_COLUMNS)
    for ax, cfg in zip(axes, cfgs, strict=True):
        _cycles(ax, cfg, mean_label=False)
        mean = f": mean {cfg.energy_mean_j:.2f} J" if math.isfinite(cfg.energy_mean_j) else ""
        panel_style(ax, "Cycle", ENERGY_LABEL, f"{cfg.joint}{mean}")
    grid_legend(axes)
    return to_data_uri(fig)


def joints_bouc_wen_figure(cfgs: Sequence[Configuration]) -> str:
    """`bouc_wen_figure` of each joint with a Bouc-Wen fit: its loop and its torque per sample, per joint."""
    fitted = [cfg for cfg in cfgs if cfg.bouc_wen is not None]
    fig, axes = new_grid(2 * len(fitted), GRID_COLUMNS)
    for k, cfg in enumerate(fitted):
        ax_l, ax_s = axes[2 * k], axes[2 * k + 1]
        _bouc_wen(ax_l, ax_s, cfg)
        panel_style(ax_l, "Centred angle (deg)", "Centred torque (N·m)", f"{cfg.joint}: loop")
        panel_style(ax_s, "Sample (decimated)", "Centred torque (N·m)", f"{cfg.joint}: per sample")
    grid_legend(axes)
    return to_data_uri(fig)


def phase_figure(cfgs: Sequence[Configuration]) -> str:
    """The angle of the first driven joint against the second's over the first recorded trial, brace on:
    measured and commanded (the motion's coordination, e.g. hip against knee)."""
    fig, (ax,) = new_figure("single")
    x_cfg, y_cfg = cfgs[0], cfgs[1]
    trial = next((t for t in x_cfg.trials if t.brace_on is not None), None)
    other = next((t for t in y_cfg.trials if trial is not None and t.number == trial.number), None)
    if trial is None or other is None or trial.brace_on is None or other.brace_on is None:
        empty(ax, "no trial")
        number = 1
    else:
        x, y = trial.brace_on, other.brace_on
        n = min(x.angle_deg.size, y.angle_deg.size)
        ax.plot(x.angle_deg[:n], y.angle_deg[:n], lw=0.6, color=COLORS[0], label="measured")
        m = min(x.command_deg.size, y.command_deg.size)
        ax.plot(x.command_deg[:m], y.command_deg[:m], ":", lw=0.8, color="k", label="command")
        number = trial.number
    title = f"{x_cfg.joint} against {y_cfg.joint}, trial {number}, brace on"
    return finish(fig, ax, f"{x_cfg.joint} angle (deg)", f"{y_cfg.joint} angle (deg)", title)


def per_joint(
    one: Callable[[Configuration], str], several: Callable[[Sequence[Configuration]], str]
) -> Callable[[Sequence[Configuration]], str]:
    """A figure of a configuration's joints: `one` of its only joint, else `several`."""
    return lambda cfgs: one(cfgs[0]) if len(cfgs) == 1 else several(cfgs)


# ---------------------------------------------------------------------------------------- calibration


def calibration_figure(set_name: str, checks: Sequence[CalibrationCheck]) -> str:
    """The calibration step responses of one set, before and after (Appendix A "Calibration"); with several
    joints, one panel per joint."""
    joints = list(dict.fromkeys(c.joint for c in checks))
    if len(joints) > 1:
        fig, axes = new_grid(len(joints), GRID_COLUMNS)
        for ax, joint in zip(axes, joints, strict=True):
            _steps(ax, [c for c in checks if c.joint == joint])
            panel_style(ax, TIME_LABEL, ANGLE_LABEL, joint)
        grid_legend(axes)
        return to_data_uri(fig)
    fig, (ax,) = new_figure("single")
    _steps(ax, checks)
    if not checks:
        empty(ax, "no calibration check")
    return finish(fig, ax, TIME_LABEL, ANGLE_LABEL, f"Set {set_name}: step responses (dotted: command)")


def _steps(ax: Axes, checks: Sequence[CalibrationCheck]) -> None:
    for i, check in enumerate(checks):
        color = COLORS[i % len(COLORS)]
        ax.plot(check.time_s, check.angle_deg, lw=0.9, color=color, label=f"{check.when}: {check.verdict}")
        if check.command_deg.size:
            ax.plot(check.command_time_s, check.command_deg, ":", lw=0.8, color=color)


# ----------------------------------------------------------------------------------------- comparisons


def _overlay_loops(ax: Axes, configs: Sequence[Configuration], label: Callable[[Configuration], str]) -> bool:
    """The first processed trial of each configuration as a brace-torque loop; False if none had data."""
    drawn = False
    for i, cfg in enumerate(configs):
        p = next((t.processed for t in cfg.trials if t.processed is not None), None)
        if p is None:
            continue
        ax.plot(p.angle_deg, p.brace_torque_nm, lw=0.7, color=COLORS[i % len(COLORS)], label=label(cfg))
        drawn = True
    return drawn


def _references(ax: Axes, data: ReportData) -> None:
    for ref in data.references:
        ax.plot(ref.angle_deg, ref.torque_nm, ".", ms=1.5, color="k", alpha=0.5, label=ref.title)


def comparison_overlay_figure(data: ReportData, comparison: Comparison) -> str:
    """Loops of the compared configurations overlaid (thesis Figures 32-37), first trial each, with the
    archive's reference datasets as dots; with several joints, one panel per joint (no reference: a
    reference dataset is one joint's)."""
    configs = configurations_of(data, comparison.configurations)
    axis = comparison_axis(comparison, configs)
    if data.multi_joint:
        fig, axes = new_grid(len(data.joints), GRID_COLUMNS)
        for ax, joint in zip(axes, data.joints, strict=True):
            joint_configs = configurations_of(data, comparison.configurations, joint)
            if not _overlay_loops(ax, joint_configs, axis.config_label):
                empty(ax, "no data")
            panel_style(ax, ANGLE_LABEL, TORQUE_LABEL, joint)
        grid_legend(axes)
        return to_data_uri(fig)
    fig, (ax,) = new_figure("single")
    drawn = _overlay_loops(ax, configs, axis.config_label)
    _references(ax, data)
    if not drawn:
        empty(ax, "none of these configurations has data")
    return finish(
        fig, ax, ANGLE_LABEL, TORQUE_LABEL, f"§{comparison.section} {comparison.title}".replace("§ ", "")
    )


def energy_bars_figure(data: ReportData, comparison: Comparison) -> str:
    """Mean energy per cycle ± one standard deviation against the compared factor (Figures 41-46).

    A scalar axis quantity with a distinct value per configuration gives a numeric axis (points with error
    bars, each marked with its configuration key); otherwise one bar per configuration, labelled with the
    level and quantity, its key written at the bar's foot."""
    if data.multi_joint:
        return joints_energy_bars_figure(data, comparison)
    fig, (ax,) = new_figure("bars")
    cfgs = [c for c in configurations_of(data, comparison.configurations) if c.energy_loss_j.size]
    axis = comparison_axis(comparison, configurations_of(data, comparison.configurations))
    if not cfgs:
        empty(ax, "no energy data")
        style(ax, axis.label, ENERGY_LABEL, _energy_title(comparison.title))
        return to_data_uri(fig)
    means = [c.energy_mean_j for c in cfgs]
    stds = [c.energy_std_j if math.isfinite(c.energy_std_j) else 0.0 for c in cfgs]
    xs = [axis.value(c) for c in cfgs]
    if axis.numeric and len(set(xs)) == len(xs) and all(math.isfinite(x) for x in xs):
        order = np.argsort(xs)
        ax.errorbar(
            np.asarray(xs)[order],
            np.asarray(means)[order],
            yerr=np.asarray(stds)[order],
            fmt="o-",
            ms=4,
            lw=0.8,
            capsize=3,
            color=COLORS[0],
        )
        for xv, m, c in zip(xs, means, cfgs, strict=True):
            ax.annotate(str(c.key), (xv, m), textcoords="offset points", xytext=(4, 4), fontsize=6.5)
        ax.set_xticks(sorted(xs))
        ax.tick_params(axis="x", labelsize=6.5)
    else:
        x = np.arange(len(cfgs))
        ax.bar(
            x,
            means,
            yerr=stds,
            capsize=3,
            color=[COLORS[i % len(COLORS)] for i in range(len(cfgs))],
            width=0.6,
        )
        for xi, c in zip(x, cfgs, strict=True):
            ax.text(float(xi), 0.0, str(c.key), ha="center", va="bottom", fontsize=6.5, color="white")
        ax.set_xticks(x, [axis.tick_label(c) for c in cfgs], fontsize=5.5)
    ax.set_ylim(bottom=0.0)
    style(ax, axis.label, ENERGY_LABEL, _energy_title(comparison.title))
    return to_data_uri(fig)


def _energy_title(title: str) -> str:
    return title if title.lower().startswith("energy") else f"Energy loss: {title}"


def joints_energy_bars_figure(data: ReportData, comparison: Comparison) -> str:
    """The energy per cycle (mean ± one standard deviation) of each compared configuration, grouped by
    joint, and of all joints together (`total_energy_loss_j`) last: one bar per configuration in each
    group, in the same colour in every group."""
    configs = configurations_of(data, comparison.configurations)
    axis = comparison_axis(comparison, configs)
    groups = [*data.joints, ALL_JOINTS]
    bar_w = 0.8 / max(1, len(configs))
    width_in = min(11.0, 1.2 + 0.2 * len(groups) * (len(configs) + 1) + KEY_IN)
    fig = Figure(figsize=(max(width_in, 5.6), 3.4), dpi=DPI)
    key_share = KEY_IN / fig.get_figwidth()
    ax = fig.add_axes((0.75 / fig.get_figwidth(), 0.3, 1.0 - key_share - 0.95 / fig.get_figwidth(), 0.6))
    x = np.arange(len(groups))
    for i, cfg in enumerate(configs):
        energies = [data.configuration(cfg.key, joint) for joint in data.joints]
        means = [e.energy_mean_j if e is not None else math.nan for e in energies]
        stds = [e.energy_std_j if e is not None else math.nan for e in energies]
        total = data.total(cfg.key)
        means.append(total.energy_mean_j if total is not None else math.nan)
        stds.append(total.energy_std_j if total is not None else math.nan)
        ax.bar(
            x + (i - (len(configs) - 1) / 2) * bar_w,
            np.nan_to_num(means),
            width=bar_w,
            yerr=np.nan_to_num(stds),
            capsize=2,
            color=COLORS[i % len(COLORS)],
            label=axis.config_label(cfg),
        )
    ax.set_xticks(x, groups, rotation=30, ha="right", fontsize=6.5)
    ax.set_ylim(bottom=0.0)
    style(ax, "", ENERGY_LABEL, "Energy per cycle, per joint and all joints together")
    legend(ax)
    return to_data_uri(fig)


def reference_figure(data: ReportData) -> str:
    """The archive's reference datasets (e.g. a reference suit's measurements, thesis §5.6, Figure 38)."""
    fig, (ax,) = new_figure("single")
    _references(ax, data)
    if not data.references:
        empty(ax, "no reference dataset")
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, "Reference data")


def element_fit_figure(data: ReportData, comparison: Comparison) -> str:
    """The fitted elastic elements against the loops' midline for each compared configuration: solid with
    dots the midline data (the fit's target), dashed the model on it. A configuration whose fit does not
    apply (e.g. no elastic element) is named in the key as not fitted. With several joints, one panel per
    joint that has an element fit."""
    configs = configurations_of(data, comparison.configurations)
    axis = comparison_axis(comparison, configs)
    if data.multi_joint:
        by_joint = {joint: configurations_of(data, comparison.configurations, joint) for joint in data.joints}
        fitted = {joint: cs for joint, cs in by_joint.items() if any(c.element_fit is not None for c in cs)}
        fig, axes = new_grid(len(fitted), GRID_COLUMNS)
        for ax, (joint, cs) in zip(axes, fitted.items(), strict=True):
            _element_fits(ax, cs, axis, note=False)
            panel_style(ax, ANGLE_LABEL, TORQUE_LABEL, joint)
        grid_legend(axes)
        return to_data_uri(fig)
    fig, (ax,) = new_figure("single")
    _element_fits(ax, configs, axis, note=True)
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, f"Elastic model vs midline: {comparison.title}")


def _element_fits(ax: Axes, configs: Sequence[Configuration], axis: ComparisonAxis, *, note: bool) -> None:
    drawn = False
    for i, cfg in enumerate(configs):
        fit = cfg.element_fit
        if fit is None:
            continue
        color = COLORS[i % len(COLORS)]
        if not fit.drawable:
            # an empty line: no data, but a key entry saying why nothing is drawn for this configuration
            ax.plot(
                [],
                [],
                linestyle="none",
                color="#666666",
                label=f"{axis.config_label(cfg)}: not fitted (see the table)",
            )
            continue
        if fit.torque_nm.size == fit.angle_deg.size:
            ax.plot(fit.angle_deg, fit.torque_nm, "o-", ms=2.5, lw=1.0, color=color, alpha=0.45)
        ax.plot(
            fit.angle_deg,
            fit.model_torque_nm,
            "--",
            lw=1.2,
            color=color,
            label=f"{axis.config_label(cfg)}, RMSE {fit.rmse_nm:.2f} N·m" if note else axis.config_label(cfg),
        )
        drawn = True
    if not drawn:
        empty(ax, "no applicable element fit")
    elif note:
        ax.text(
            0.98,
            0.03,
            "solid with dots: midline data\ndashed: elastic model",
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=6.5,
            color="#444444",
        )


# ---------------------------------------------------------------------------------------- predictions
# Drawn where the predictions are computed (`report.predictions.predictions`).

MEASURED_COLOR = COLORS[0]
PREDICTED_COLOR = COLORS[1]
FITTED_RANGE_COLOR = "0.9"  # light grey, behind the loops


def prediction_figure(
    fit_key: int,
    predict_key: int,
    angle_deg: npt.ArrayLike,
    measured_torque_nm: npt.ArrayLike,
    predicted_torque_nm: npt.ArrayLike,
    fitted_range_deg: tuple[float, float] | None = None,
) -> str:
    """Configuration `predict_key`'s measured loop (solid, blue) and the loop the element model fitted on
    `fit_key` predicts (dashed, red), drawn in that order: the prediction over the data it is judged
    against; behind them, shaded grey, the angles the model was fitted on (`fitted_range_deg`, when given):
    where the loop leaves them, the model extrapolates."""
    fig, (ax,) = new_figure("single")
    angle = np.asarray(angle_deg, dtype=np.float64)
    if angle.size == 0:
        empty(ax, f"no element model of configuration {fit_key}")
    else:
        if fitted_range_deg is not None:
            low, high = fitted_range_deg
            ax.axvspan(low, high, color=FITTED_RANGE_COLOR, zorder=0, label=f"angles fitted on {fit_key}")
        ax.plot(
            angle,
            measured_torque_nm,
            lw=0.7,
            color=MEASURED_COLOR,
            label=f"measured, configuration {predict_key}",
        )
        ax.plot(
            angle,
            predicted_torque_nm,
            lw=0.9,
            ls="--",
            color=PREDICTED_COLOR,
            label=f"element model fitted on {fit_key}",
        )
    title = f"Configuration {predict_key} predicted from {fit_key}"
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, title)


# ------------------------------------------------------------------------------- session comparison


def overlay_figure(a: Configuration, b: Configuration) -> str | None:
    """Brace torque against angle, every processed trial of A (blue) and B (red); None without data."""
    if not (a.has_data or b.has_data):
        return None
    fig, (ax,) = new_figure("single")
    for cfg, color, name in ((a, "#1f77b4", "A"), (b, "#d62728", "B")):
        first = True
        for p in (t.processed for t in cfg.trials if t.processed is not None):
            ax.plot(
                p.angle_deg,
                p.brace_torque_nm,
                color=color,
                linewidth=0.7,
                alpha=0.8,
                label=f"{name}: configuration {cfg.key}" if first else None,
            )
            first = False
    style(ax, ANGLE_LABEL, TORQUE_LABEL)
    legend(ax)
    return to_data_uri(fig)


# ---------------------------------------------------------------------------------------------- driver

DRAW: dict[str, Callable[..., str]] = {
    "calibration": calibration_figure,
    "hysteresis": per_joint(hysteresis_figure, joints_hysteresis_figure),
    "time": per_joint(time_series_figure, joints_time_figure),
    "energy": per_joint(energy_cycles_figure, joints_energy_figure),
    "boucwen": per_joint(bouc_wen_figure, joints_bouc_wen_figure),
    "phase": phase_figure,
    "comparison_overlay": comparison_overlay_figure,
    "energy_bars": energy_bars_figure,
    "reference": reference_figure,
    "element_fit": element_fit_figure,
}
"""The drawing function of each kind of figure (`figure_plan.figure_jobs`)."""


def _tasks(data: ReportData) -> list[tuple[str, Callable[[], str]]]:
    return [(figure_id, functools.partial(DRAW[kind], *args)) for figure_id, kind, args in figure_jobs(data)]


def assemble_figures(data: ReportData, workers: int | None = None) -> FigureSet:
    """Every figure of the report, drawn by this process, or with `workers` > 1 (None: `default_workers`)
    on that many worker processes (`parallel.map_in_processes`); a figure that cannot be drawn is missing,
    with the reason."""
    every = figure_ids(data)
    n_workers = default_workers(len(every)) if workers is None else workers
    results: list[Drawn] | None = None
    if n_workers > 1 and len(every) >= 8:
        # small chunks keep both workers busy: two-panel figures cost about twice a one-panel one
        results = map_in_processes(
            _run_one, every, n_workers, initializer=_init_worker, initargs=(data,), chunksize=4
        )
    if results is None:
        tasks = dict(_tasks(data))
        results = [_safe(figure_id, tasks[figure_id]) for figure_id in every]
    drawn = {figure_id: (uri, error) for figure_id, uri, error in results}
    images = {figure_id: uri for figure_id in every if (uri := drawn[figure_id][0]) is not None}
    missing = {
        figure_id: drawn[figure_id][1] or "not drawn" for figure_id in every if figure_id not in images
    }
    return FigureSet(images=images, missing=missing)


_WORKER_TASKS: dict[str, Callable[[], str]] = {}


def _init_worker(data: ReportData) -> None:
    _WORKER_TASKS.clear()
    _WORKER_TASKS.update(_tasks(data))


def _run_one(task_id: str) -> Drawn:
    return _safe(task_id, _WORKER_TASKS[task_id])


def _safe(task_id: str, task: Callable[[], str]) -> Drawn:
    try:
        return task_id, task(), None
    except (ValueError, TypeError, IndexError, FloatingPointError) as exc:  # bad data never kills the report
        return task_id, None, f"{type(exc).__name__}: {exc}"
