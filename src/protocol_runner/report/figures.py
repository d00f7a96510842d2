"""The report's figures: matplotlib (Agg, no pyplot state) rendered to PNG data URIs.

Every figure function takes report data and returns a `data:image/png;base64,...` string. Units and
axis labels are the same everywhere: angle in degrees, torque in N·m, time in seconds, energy in joules.
The figures follow the thesis: hysteresis loops as in Appendix B, and for each comparison the protocol
declares, overlaid loops as in §5.1-5.5 (Figures 32-37) and the energy per cycle against the compared
factor as in §5.7.2 (Figures 41-46, here with error bars: ± one standard deviation across cycles and
trials); the archive's reference datasets (§5.6, Figure 38); the fitted elastic elements against the
loops' midline as in §6.1.5 (Figures 52-53) and the Bouc-Wen model against the data as in §6.2.4
(Figures 57-58).

Which figures there are, and `render_figures(data)`, which has them all drawn and returns a `FigureSet`
mapping figure ids (used as HTML element ids) to data URIs, are in `figure_plan` (no matplotlib); here each
kind of figure is drawn (`DRAW`), by this process or by worker processes (`draw_here`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

import numpy as np
from matplotlib.ticker import MaxNLocator

from protocol_runner.report.drawing import (
    ANGLE_LABEL,
    COLORS,
    ENERGY_LABEL,
    TIME_LABEL,
    TORQUE_LABEL,
    empty,
    finish,
    legend,
    new_figure,
    style,
    to_data_uri,
)
from protocol_runner.report.figure_plan import (
    Drawn,
    FigureDrawer,
    FigureSet,
    assemble_figures,
    configuration_jobs,
    figure_jobs,
)
from protocol_runner.report.figures_compare import (
    comparison_overlay_figure,
    element_fit_figure,
    energy_bars_figure,
    reference_figure,
)
from protocol_runner.report.model import CalibrationCheck, Configuration, ReportData
from protocol_runner.report.parallel import map_in_processes

# ------------------------------------------------------------------------------------ per configuration


def hysteresis_figure(cfg: Configuration) -> str:
    """Brace torque against angle, every trial (Appendix B), with the fitted elastic model if any."""
    fig, (ax,) = new_figure("single")
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
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, f"Configuration {cfg.key}: brace torque vs angle")


def time_series_figure(cfg: Configuration) -> str:
    """Angle and torque against time for trial 1, brace on and brace off (thesis §4.3)."""
    fig, (ax_a, ax_t) = new_figure("double")
    trial = next((t for t in cfg.trials if t.brace_on is not None or t.brace_off is not None), None)
    if trial is None:
        empty(ax_a, "no trial")
        empty(ax_t, "no trial")
    else:
        for rec, name, color in (
            (trial.brace_on, "brace on", COLORS[0]),
            (trial.brace_off, "brace off", COLORS[1]),
        ):
            if rec is None:
                continue
            ax_a.plot(rec.time_s, rec.angle_deg, lw=0.6, color=color, label=name)
            ax_t.plot(rec.time_s, rec.torque_nm, lw=0.6, color=color, label=name)
        if trial.brace_on is not None and trial.brace_on.command_deg.size:
            ax_a.plot(
                trial.brace_on.command_time_s,
                trial.brace_on.command_deg,
                ":",
                lw=0.8,
                color="k",
                label="command",
            )
    number = trial.number if trial is not None else 1
    style(ax_a, TIME_LABEL, ANGLE_LABEL, f"Angle, trial {number}")
    style(ax_t, TIME_LABEL, TORQUE_LABEL, f"Joint torque, trial {number}")
    legend(ax_a)
    return to_data_uri(fig)


def energy_cycles_figure(cfg: Configuration) -> str:
    """Energy lost per complete cycle (Eq 10-12), each trial in its colour, with the mean ± std band."""
    fig, (ax,) = new_figure("single")
    e = cfg.energy_loss_j
    if e.size == 0:
        empty(ax, "no complete cycle")
    else:
        trials = cfg.energy_cycle_trial
        index = np.arange(1, e.size + 1)
        for i, number in enumerate(sorted(set(trials.tolist()))):
            sel = trials == number
            ax.plot(
                index[sel], e[sel], "o", ms=3.5, color=COLORS[i % len(COLORS)], label=f"trial {int(number)}"
            )
        mean, std = cfg.energy_mean_j, cfg.energy_std_j
        ax.axhline(mean, color="k", lw=0.8, label=f"mean {mean:.2f} J")
        if math.isfinite(std):
            ax.axhspan(mean - std, mean + std, color="k", alpha=0.08, lw=0)
        ax.xaxis.set_major_locator(MaxNLocator(nbins=5, integer=True))  # cycles are counted: 1, 2, 3
        top = float(np.nanmax(e)) if np.isfinite(e).any() else 1.0
        ax.set_ylim(0.0, max(top, mean + (std if math.isfinite(std) else 0.0)) * 1.15 or 1.0)
    title = f"Configuration {cfg.key}: energy lost per cycle"
    return finish(fig, ax, "Cycle (all trials in order)", ENERGY_LABEL, title, bottom=True)


def bouc_wen_figure(cfg: Configuration) -> str:
    """Bouc-Wen model against the centred data: loop overlay (Fig 57) and torque per sample (Fig 58)."""
    fig, (ax_l, ax_s) = new_figure("double")
    bw = cfg.bouc_wen
    if bw is None or bw.angle_deg.size == 0:
        empty(ax_l, "no Bouc-Wen fit")
        empty(ax_s, "no Bouc-Wen fit")
    else:
        ax_l.plot(bw.angle_deg, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
        ax_l.plot(bw.angle_deg, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")
        sample = np.arange(bw.torque_nm.size)
        ax_s.plot(sample, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
        ax_s.plot(sample, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")
    style(ax_l, "Centred angle (deg)", "Centred torque (N·m)", "Hysteresis: model vs data")
    style(ax_s, "Sample (decimated)", "Centred torque (N·m)", "Torque: model vs data")
    legend(ax_l)
    return to_data_uri(fig)


# ---------------------------------------------------------------------------------------- calibration


def calibration_figure(set_name: str, checks: Sequence[CalibrationCheck]) -> str:
    """The calibration step responses of one set, before and after (Appendix A "Calibration")."""
    fig, (ax,) = new_figure("single")
    for i, check in enumerate(checks):
        color = COLORS[i % len(COLORS)]
        ax.plot(check.time_s, check.angle_deg, lw=0.9, color=color, label=f"{check.when}: {check.verdict}")
        if check.command_deg.size:
            ax.plot(check.command_time_s, check.command_deg, ":", lw=0.8, color=color)
    if not checks:
        empty(ax, "no calibration check")
    return finish(fig, ax, TIME_LABEL, ANGLE_LABEL, f"Set {set_name}: step responses (dotted: command)")


# ---------------------------------------------------------------------------------------------- driver

DRAW: dict[str, Callable[..., str]] = {
    "calibration": calibration_figure,
    "hysteresis": hysteresis_figure,
    "time": time_series_figure,
    "energy": energy_cycles_figure,
    "boucwen": bouc_wen_figure,
    "comparison_overlay": comparison_overlay_figure,
    "energy_bars": energy_bars_figure,
    "reference": reference_figure,
    "element_fit": element_fit_figure,
}
"""The drawing function of each kind of figure (`figure_plan.figure_jobs`)."""


def _tasks(data: ReportData) -> list[tuple[str, Callable[[], str]]]:
    return [(figure_id, _bind(DRAW[kind], *args)) for figure_id, kind, args in figure_jobs(data)]


def configuration_tasks(cfg: Configuration) -> list[tuple[str, Callable[[], str]]]:
    """The figures of one configuration (`figure_plan.configuration_jobs`), ready to draw."""
    return [(figure_id, _bind(DRAW[kind], *args)) for figure_id, kind, args in configuration_jobs(cfg)]


def draw_configuration(cfg: Configuration) -> dict[str, str] | None:
    """Every figure of `cfg` as id -> data URI, or None if one of them cannot be drawn."""
    images: dict[str, str] = {}
    for task_id, task in configuration_tasks(cfg):
        _, uri, _ = _safe(task_id, task)
        if uri is None:
            return None
        images[task_id] = uri
    return images


def _bind(fn: Callable[..., str], *args: object) -> Callable[[], str]:
    return functools.partial(fn, *args)


def draw_figures(data: ReportData, task_ids: list[str]) -> list[Drawn]:
    """The figures `task_ids` of `data`, in order (run by a process that draws for another)."""
    tasks = dict(_tasks(data))
    return [_safe(task_id, tasks[task_id]) for task_id in task_ids]


def render_figures(
    data: ReportData, workers: int | None = None, *, draw: FigureDrawer | None = None
) -> FigureSet:
    """Draw every figure of the report (those drawn ahead for this data are taken from the figure cache).
    `draw` draws them elsewhere; else `workers` > 1 draws on that many worker processes."""
    return assemble_figures(data, workers, draw=draw, here=draw_here)


def draw_here(data: ReportData, task_ids: list[str], workers: int) -> list[Drawn]:
    """The figures `task_ids` of `data` drawn by this process, or with `workers` > 1 (and enough figures)
    on that many worker processes (`parallel.map_in_processes`)."""
    results: list[Drawn] | None = None
    if workers > 1 and len(task_ids) >= 8:
        # small chunks keep both workers busy: two-panel figures cost about twice a one-panel one
        results = map_in_processes(
            _run_one, task_ids, workers, initializer=_init_worker, initargs=(data,), chunksize=4
        )
    if results is None:
        results = draw_figures(data, task_ids)
    return results


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
