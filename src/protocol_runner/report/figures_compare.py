"""The report's cross-configuration figures, one set per declared comparison: overlaid loops, energy per
cycle against the compared factor, the reference datasets, and the fitted elastic elements against the
loops' midline (the knee thesis's §5.1-5.5, §5.7.2 and §6.1.5 figures, made generic).

Labels and axes come from `comparison_values.comparison_axis` (the compared factor's level labels and
quantities with the unit from the quantity's suffix); nothing here knows a factor's name."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report import drawing
from protocol_runner.report.comparison_values import ComparisonAxis, comparison_axis
from protocol_runner.report.drawing import (
    ANGLE_LABEL,
    COLORS,
    DPI,
    ENERGY_LABEL,
    GRID_COLUMNS,
    KEY_IN,
    TORQUE_LABEL,
    empty,
    finish,
    grid_legend,
    legend,
    new_figure,
    new_grid,
    panel_style,
    style,
    to_data_uri,
)
from protocol_runner.report.figure_plan import configurations_of
from protocol_runner.report.model import Configuration, ReportData

# ----------------------------------------------------------------------------------------- comparisons


def _overlay_loops(ax: Axes, configs: Sequence[Configuration], label: Callable[[Configuration], str]) -> bool:
    """The first processed trial of each configuration as a brace-torque loop; False if none had data."""
    drawn = False
    for i, cfg in enumerate(configs):
        trial = next((t for t in cfg.trials if t.processed is not None), None)
        if trial is None or trial.processed is None:
            continue
        ax.plot(
            trial.processed.angle_deg,
            trial.processed.brace_torque_nm,
            lw=0.7,
            color=COLORS[i % len(COLORS)],
            label=label(cfg),
        )
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
            if not _overlay_loops(
                ax, configurations_of(data, comparison.configurations, joint), axis.config_label
            ):
                empty(ax, "no data")
            panel_style(ax, ANGLE_LABEL, TORQUE_LABEL, joint)
        grid_legend(axes)
        return drawing.to_data_uri(fig)
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


ALL_JOINTS = "all joints"


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
    return drawing.to_data_uri(fig)


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
        joints = [
            joint
            for joint in data.joints
            if any(
                c.element_fit is not None for c in configurations_of(data, comparison.configurations, joint)
            )
        ]
        fig, axes = new_grid(len(joints), GRID_COLUMNS)
        for ax, joint in zip(axes, joints, strict=True):
            _element_fits(ax, configurations_of(data, comparison.configurations, joint), axis, note=False)
            panel_style(ax, ANGLE_LABEL, TORQUE_LABEL, joint)
        grid_legend(axes)
        return drawing.to_data_uri(fig)
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
