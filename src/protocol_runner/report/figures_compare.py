"""The report's cross-configuration figures: comparison overlays (§5.1-5.5), energy-loss bars (§5.7.2),
restraint bars, the EMU comparison (§5.6) and the physical model against the data (§6.1.5)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from matplotlib.axes import Axes

from protocol_runner.report.canvas import (
    ANGLE_LABEL,
    COLORS,
    ENERGY_LABEL,
    TORQUE_LABEL,
    canvas_axes,
    config_label,
    empty,
    legend,
    style,
    to_data_uri,
)
from protocol_runner.report.findings import comparison_keys
from protocol_runner.report.model import Comparison, Configuration, ReportData

# ----------------------------------------------------------------------------------------- comparisons


def configurations_of(data: ReportData, keys: Sequence[int]) -> list[Configuration]:
    return [c for k in keys if (c := data.configuration(k)) is not None]


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


def comparison_overlay_figure(data: ReportData, comparison: Comparison) -> str:
    """Hysteresis loops of the compared configurations overlaid (thesis Figures 32-37), trial 1 each."""
    fig, (ax,) = canvas_axes("single")
    drawn = _overlay_loops(
        ax,
        configurations_of(data, comparison.configurations),
        lambda c: config_label(c, comparison.parameter),
    )
    if not drawn:
        empty(ax, "none of these configurations has data")
    style(ax, ANGLE_LABEL, TORQUE_LABEL, f"§{comparison.section} {comparison.title}")
    legend(ax)
    return to_data_uri(fig)


def energy_bars_figure(data: ReportData, comparison: Comparison) -> str:
    """Mean energy per cycle with ± one standard deviation (thesis Figures 41-46 with error bars)."""
    fig, (ax,) = canvas_axes("bars")
    cfgs = [c for c in configurations_of(data, comparison.configurations) if c.energy_loss_j.size]
    if not cfgs:
        empty(ax, "no energy data")
    else:
        x = np.arange(len(cfgs))
        means = [c.energy_mean_j for c in cfgs]
        stds = [c.energy_std_j if math.isfinite(c.energy_std_j) else 0.0 for c in cfgs]
        ax.bar(
            x,
            means,
            yerr=stds,
            capsize=3,
            color=[COLORS[i % len(COLORS)] for i in range(len(cfgs))],
            width=0.6,
        )
        ax.set_xticks(x, [config_label(c, comparison.parameter) for c in cfgs], fontsize=6.5)
    style(ax, "", ENERGY_LABEL, f"Energy loss: {comparison.title}")
    return to_data_uri(fig)


def restraint_bars_figure(data: ReportData) -> str:
    """Restrained range (brace stops) against a smaller trajectory, paired by stop (thesis Figure 42)."""
    fig, (ax,) = canvas_axes("bars")
    restrained = [
        c for c in configurations_of(data, comparison_keys(data, "brace_rom")) if c.energy_loss_j.size
    ]
    trajectory = [
        c for c in configurations_of(data, comparison_keys(data, "robot_rom")) if c.energy_loss_j.size
    ]
    if not restrained and not trajectory:
        empty(ax, "no energy data")
    else:
        for offset, group, name, color in (
            (-0.2, restrained, "stops (brace ROM)", COLORS[0]),
            (0.2, trajectory, "trajectory (robot ROM)", COLORS[1]),
        ):
            if not group:
                continue
            x = np.arange(len(group)) + offset
            ax.bar(
                x,
                [c.energy_mean_j for c in group],
                yerr=[c.energy_std_j if math.isfinite(c.energy_std_j) else 0.0 for c in group],
                width=0.38,
                capsize=3,
                color=color,
                label=name,
            )
            for xi, c in zip(x, group, strict=True):
                ax.text(xi, 0.0, str(c.key), ha="center", va="bottom", fontsize=6.5, color="white")
        n = max(len(restrained), len(trajectory))
        ax.set_xticks(np.arange(n), [f"range {i + 1}" for i in range(n)], fontsize=6.5)
    style(ax, "", ENERGY_LABEL, "Energy loss: restrained range vs smaller trajectory")
    legend(ax)
    return to_data_uri(fig)


def emu_figure(data: ReportData, comparison: Comparison) -> str:
    """The EMU-condition configurations against the reference dataset (thesis §5.6, Figure 38)."""
    fig, (ax,) = canvas_axes("single")
    _overlay_loops(
        ax, configurations_of(data, comparison.configurations), lambda c: f"config {c.key} ({c.profile})"
    )
    for ref in data.references:
        ax.plot(ref.angle_deg, ref.torque_nm, ".", ms=1.5, color="k", alpha=0.6, label=ref.title)
    style(ax, ANGLE_LABEL, TORQUE_LABEL, "EMU condition vs reference data")
    legend(ax)
    return to_data_uri(fig)


def spring_model_figure(data: ReportData, comparison: Comparison) -> str:
    """Physical spring model (Eq 13-18) against the data for a preload or spring change (Figs 52-53)."""
    fig, (ax,) = canvas_axes("single")
    drawn = False
    for i, cfg in enumerate(configurations_of(data, comparison.configurations)):
        color = COLORS[i % len(COLORS)]
        trial = next((t for t in cfg.trials if t.processed is not None), None)
        if trial is not None and trial.processed is not None:
            ax.plot(
                trial.processed.angle_deg, trial.processed.brace_torque_nm, lw=0.5, color=color, alpha=0.55
            )
            drawn = True
        if cfg.spring is not None and cfg.spring.applicable and cfg.spring.angle_deg.size:
            ax.plot(
                cfg.spring.angle_deg,
                cfg.spring.model_torque_nm,
                "--",
                lw=1.2,
                color=color,
                label=f"model, {config_label(cfg, comparison.parameter)}",
            )
            drawn = True
    if not drawn:
        empty(ax, "no data")
    style(ax, ANGLE_LABEL, TORQUE_LABEL, f"Physical model vs data: {comparison.title}")
    legend(ax)
    return to_data_uri(fig)
