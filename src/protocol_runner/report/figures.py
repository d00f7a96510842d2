"""The report's figures: matplotlib (Agg, no pyplot state) rendered to PNG data URIs.

Every figure function takes report data and returns a `data:image/png;base64,...` string. Units and
axis labels are the same everywhere: angle in degrees, torque in N·m, time in seconds, energy in joules.
The figures follow the thesis: hysteresis loops as in Appendix B, comparison overlays as in §5.1-5.5
(Figures 32-37), energy-loss bars as in §5.7.2 (Figures 41-46, here with error bars: ± one standard
deviation across cycles and trials), the EMU comparison of §5.6 (Figure 38), the physical model against
the data as in §6.1.5 (Figures 52-53) and the Bouc-Wen model against the data as in §6.2.4 (Figures
57-58).

`render_figures(data)` draws them all, optionally on worker processes (`workers`), and returns a
`FigureSet` mapping figure ids (used as HTML element ids) to data URIs.
"""

from __future__ import annotations

import base64
import functools
import io
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.container import Container
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator, ScalarFormatter

from protocol_runner.report.findings import comparison_keys
from protocol_runner.report.model import CalibrationCheck, Comparison, Configuration, ReportData
from protocol_runner.report.parallel import map_in_processes

DPI = 80
ANGLE_LABEL = "Angle (deg)"
TORQUE_LABEL = "Torque (N·m)"
TIME_LABEL = "Time (s)"
ENERGY_LABEL = "Energy per cycle (J)"
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf")


@dataclass(frozen=True)
class FigureSet:
    """Figure id -> data URI, plus ids whose figure could not be drawn (with the reason)."""

    images: dict[str, str] = field(default_factory=dict)
    missing: dict[str, str] = field(default_factory=dict)

    def get(self, figure_id: str) -> str | None:
        """The data URI of `figure_id`, or None."""
        return self.images.get(figure_id)


# ----------------------------------------------------------------------------------------- drawing kit


class _Canvas:
    """One Figure of a given kind, reused for every figure of that kind (its axes and ticks persist).

    Matplotlib spends most of a small figure's time creating tick and text objects; clearing only the
    plotted artists between uses keeps them (the report draws several figures per configuration).
    Not thread-safe: each process draws one figure at a time.
    """

    def __init__(self, width_in: float, height_in: float, rects: Sequence[tuple[float, float, float, float]]):
        self.fig = Figure(figsize=(width_in, height_in), dpi=DPI)
        FigureCanvasAgg(self.fig)
        self.axes = [self.fig.add_axes(rect) for rect in rects]
        for ax in self.axes:
            # fixed label positions: matplotlib otherwise measures every tick label to place them
            ax.xaxis.set_label_coords(0.5, -0.11)
            ax.yaxis.set_label_coords(-0.11 if len(rects) == 1 else -0.17, 0.5)

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


_CANVASES: dict[str, _Canvas] = {}
_LAYOUTS: dict[str, tuple[float, float, tuple[tuple[float, float, float, float], ...]]] = {
    "single": (4.6, 3.3, ((0.14, 0.14, 0.82, 0.76),)),
    "bars": (4.6, 3.0, ((0.14, 0.2, 0.82, 0.68),)),
    "double": (6.4, 3.3, ((0.10, 0.14, 0.38, 0.76), (0.60, 0.14, 0.38, 0.76))),
}


def _axes(kind: str) -> tuple[Figure, list[Axes]]:
    canvas = _CANVASES.get(kind)
    if canvas is None:
        width, height, rects = _LAYOUTS[kind]
        canvas = _CANVASES[kind] = _Canvas(width, height, rects)
    return canvas.fig, canvas.reset()


def to_data_uri(fig: Figure) -> str:
    """Encode `fig` as a PNG data URI (deterministic: no timestamp or software tag in the PNG)."""
    buf = io.BytesIO()
    # zlib level 1: about 3x faster to encode than the default 6, for slightly larger files
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None}, pil_kwargs={"compress_level": 1})
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _style(ax: Axes, xlabel: str, ylabel: str, title: str | None = None) -> None:
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    # an explicit y skips matplotlib's costly automatic title placement
    ax.set_title(title or "", fontsize=8.5, y=1.01)
    ax.grid(True, linewidth=0.4, alpha=0.5)
    ax.tick_params(labelsize=7)
    ax.autoscale_view()


def _empty(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=8, color="#666666")


def _legend(ax: Axes, *, bottom: bool = False) -> None:
    """A colour key in the top-left (or bottom-left) corner: one coloured text line per labelled artist.

    Cheaper than `Axes.legend` (whose box layout was a fifth of the report's drawing time) and
    deterministic in position (loc="best" would search the data)."""
    handles, labels = ax.get_legend_handles_labels()
    n = len(labels)
    for i, (handle, label) in enumerate(zip(handles, labels, strict=True)):
        color, glyph = _swatch(handle)
        ax.text(
            0.02,
            (0.03 + 0.066 * (n - 1 - i)) if bottom else (0.97 - 0.066 * i),
            f"{glyph} {label}",
            color=color,
            transform=ax.transAxes,
            fontsize=6.5,
            ha="left",
            va="bottom" if bottom else "top",
        )


def _swatch(handle: object) -> tuple[object, str]:
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


def config_label(cfg: Configuration, parameter: str) -> str:
    """Legend text: configuration key and the compared parameter's value with units."""
    value = _parameter_value(cfg, parameter)
    return f"{cfg.key}: {value}" if value else f"config {cfg.key}"


def _float_setting(cfg: Configuration, name: str) -> float | None:
    value = cfg.setting(name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _parameter_value(cfg: Configuration, parameter: str) -> str:
    p = parameter.lower()
    if "friction" in p:
        nm = _float_setting(cfg, "friction_nm")
        return f"{nm:.2f} N·m" if nm is not None else str(cfg.setting("friction", ""))
    if "stiff" in p or "spring" in p:
        k = _float_setting(cfg, "stiffness_n_per_mm")
        return f"{k:g} N/mm" if k is not None else str(cfg.setting("stiffness", ""))
    if "preload" in p:
        pos = cfg.setting("preload_position")
        return f"position {pos}" if pos is not None else str(cfg.setting("preload", ""))
    if "speed" in p:
        v = _float_setting(cfg, "speed_deg_s")
        return f"{v:g} deg/s" if v is not None else str(cfg.setting("speed", ""))
    if "rom" in p:
        rng = cfg.setting("brace_rom_deg" if "brace" in p else "robot_rom_deg")
        if isinstance(rng, tuple) and len(rng) == 2:
            return f"{float(rng[0]):g}-{float(rng[1]):g}°"
    value = cfg.setting(parameter)
    return "" if value is None else str(value)


# ------------------------------------------------------------------------------------ per configuration


def hysteresis_figure(cfg: Configuration) -> str:
    """Brace torque against angle, every trial (Appendix B), with the physical model's curve if fitted."""
    fig, (ax,) = _axes("single")
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
    if cfg.spring is not None and cfg.spring.applicable and cfg.spring.angle_deg.size:
        ax.plot(cfg.spring.angle_deg, cfg.spring.model_torque_nm, "k--", lw=0.9, label="spring model")
    if not drawn:
        _empty(ax, "no processed trial")
    _style(ax, ANGLE_LABEL, TORQUE_LABEL, f"Configuration {cfg.key}: brace torque vs angle")
    _legend(ax)
    return to_data_uri(fig)


def time_series_figure(cfg: Configuration) -> str:
    """Angle and torque against time for trial 1, brace on and brace off (thesis §4.3)."""
    fig, (ax_a, ax_t) = _axes("double")
    trial = next((t for t in cfg.trials if t.brace_on is not None or t.brace_off is not None), None)
    if trial is None:
        _empty(ax_a, "no trial")
        _empty(ax_t, "no trial")
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
    _style(ax_a, TIME_LABEL, ANGLE_LABEL, f"Angle, trial {number}")
    _style(ax_t, TIME_LABEL, TORQUE_LABEL, f"Joint torque, trial {number}")
    _legend(ax_a)
    return to_data_uri(fig)


def energy_cycles_figure(cfg: Configuration) -> str:
    """Energy lost per complete cycle (Eq 10-12), each trial in its colour, with the mean ± std band."""
    fig, (ax,) = _axes("single")
    e = cfg.energy_loss_j
    if e.size == 0:
        _empty(ax, "no complete cycle")
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
        top = float(np.nanmax(e)) if np.isfinite(e).any() else 1.0
        ax.set_ylim(0.0, max(top, mean + (std if math.isfinite(std) else 0.0)) * 1.15 or 1.0)
    _style(ax, "Cycle (all trials in order)", ENERGY_LABEL, f"Configuration {cfg.key}: energy lost per cycle")
    _legend(ax, bottom=True)
    return to_data_uri(fig)


def bouc_wen_figure(cfg: Configuration) -> str:
    """Bouc-Wen model against the centred data: loop overlay (Fig 57) and torque per sample (Fig 58)."""
    fig, (ax_l, ax_s) = _axes("double")
    bw = cfg.bouc_wen
    if bw is None or bw.angle_deg.size == 0:
        _empty(ax_l, "no Bouc-Wen fit")
        _empty(ax_s, "no Bouc-Wen fit")
    else:
        ax_l.plot(bw.angle_deg, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
        ax_l.plot(bw.angle_deg, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")
        sample = np.arange(bw.torque_nm.size)
        ax_s.plot(sample, bw.torque_nm, lw=0.7, color=COLORS[0], label="data")
        ax_s.plot(sample, bw.model_torque_nm, lw=0.7, color=COLORS[1], label="model")
    _style(ax_l, "Centred angle (deg)", "Centred torque (N·m)", "Hysteresis: model vs data")
    _style(ax_s, "Sample (decimated)", "Centred torque (N·m)", "Torque: model vs data")
    _legend(ax_l)
    return to_data_uri(fig)


# ---------------------------------------------------------------------------------------- calibration


def calibration_figure(set_name: str, checks: Sequence[CalibrationCheck]) -> str:
    """The calibration step responses of one set, before and after (Appendix A "Calibration")."""
    fig, (ax,) = _axes("single")
    for i, check in enumerate(checks):
        color = COLORS[i % len(COLORS)]
        ax.plot(check.time_s, check.angle_deg, lw=0.9, color=color, label=f"{check.when}: {check.verdict}")
        if check.command_deg.size:
            ax.plot(check.command_time_s, check.command_deg, ":", lw=0.8, color=color)
    if not checks:
        _empty(ax, "no calibration check")
    _style(ax, TIME_LABEL, ANGLE_LABEL, f"Set {set_name}: step responses (dotted: command)")
    _legend(ax)
    return to_data_uri(fig)


# ----------------------------------------------------------------------------------------- comparisons


def _present(data: ReportData, keys: Sequence[int]) -> list[Configuration]:
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
    fig, (ax,) = _axes("single")
    drawn = _overlay_loops(
        ax, _present(data, comparison.configurations), lambda c: config_label(c, comparison.parameter)
    )
    if not drawn:
        _empty(ax, "none of these configurations has data")
    _style(ax, ANGLE_LABEL, TORQUE_LABEL, f"§{comparison.section} {comparison.title}")
    _legend(ax)
    return to_data_uri(fig)


def energy_bars_figure(data: ReportData, comparison: Comparison) -> str:
    """Mean energy per cycle with ± one standard deviation (thesis Figures 41-46 with error bars)."""
    fig, (ax,) = _axes("bars")
    cfgs = [c for c in _present(data, comparison.configurations) if c.energy_loss_j.size]
    if not cfgs:
        _empty(ax, "no energy data")
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
    _style(ax, "", ENERGY_LABEL, f"Energy loss: {comparison.title}")
    return to_data_uri(fig)


def restraint_bars_figure(data: ReportData) -> str:
    """Restrained range (brace stops) against a smaller trajectory, paired by stop (thesis Figure 42)."""
    fig, (ax,) = _axes("bars")
    restrained = [c for c in _present(data, comparison_keys(data, "brace_rom")) if c.energy_loss_j.size]
    trajectory = [c for c in _present(data, comparison_keys(data, "robot_rom")) if c.energy_loss_j.size]
    if not restrained and not trajectory:
        _empty(ax, "no energy data")
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
    _style(ax, "", ENERGY_LABEL, "Energy loss: restrained range vs smaller trajectory")
    _legend(ax)
    return to_data_uri(fig)


def emu_figure(data: ReportData, comparison: Comparison) -> str:
    """The EMU-condition configurations against the reference dataset (thesis §5.6, Figure 38)."""
    fig, (ax,) = _axes("single")
    _overlay_loops(ax, _present(data, comparison.configurations), lambda c: f"config {c.key} ({c.profile})")
    for ref in data.references:
        ax.plot(ref.angle_deg, ref.torque_nm, ".", ms=1.5, color="k", alpha=0.6, label=ref.title)
    _style(ax, ANGLE_LABEL, TORQUE_LABEL, "EMU condition vs reference data")
    _legend(ax)
    return to_data_uri(fig)


def spring_model_figure(data: ReportData, comparison: Comparison) -> str:
    """Physical spring model (Eq 13-18) against the data for a preload or spring change (Figs 52-53)."""
    fig, (ax,) = _axes("single")
    drawn = False
    for i, cfg in enumerate(_present(data, comparison.configurations)):
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
        _empty(ax, "no data")
    _style(ax, ANGLE_LABEL, TORQUE_LABEL, f"Physical model vs data: {comparison.title}")
    _legend(ax)
    return to_data_uri(fig)


# ---------------------------------------------------------------------------------------------- driver


def figure_ids(data: ReportData) -> list[str]:
    """Ids of every figure the report shows for `data`, in document order."""
    return [task_id for task_id, _ in _tasks(data)]


def _tasks(data: ReportData) -> list[tuple[str, Callable[[], str]]]:
    tasks: list[tuple[str, Callable[[], str]]] = []
    for set_name in sorted({c.set_name for c in data.calibration}):
        checks = [c for c in data.calibration if c.set_name == set_name]
        tasks.append((f"fig-calibration-{slug(set_name)}", _bind(calibration_figure, set_name, checks)))
    for cfg in data.configurations:
        if not cfg.trials:
            continue
        base = f"fig-config-{cfg.key}"
        tasks.append((f"{base}-hysteresis", _bind(hysteresis_figure, cfg)))
        tasks.append((f"{base}-time", _bind(time_series_figure, cfg)))
        tasks.append((f"{base}-energy", _bind(energy_cycles_figure, cfg)))
        if cfg.bouc_wen is not None:
            tasks.append((f"{base}-boucwen", _bind(bouc_wen_figure, cfg)))
    for comp in distinct_comparisons(data):
        tasks.append(
            (f"fig-comparison-{slug(comp.name)}-overlay", _bind(comparison_overlay_figure, data, comp))
        )
        tasks.append((f"fig-comparison-{slug(comp.name)}-energy", _bind(energy_bars_figure, data, comp)))
    if _present(data, comparison_keys(data, "brace_rom")) or _present(
        data, comparison_keys(data, "robot_rom")
    ):
        tasks.append(("fig-energy-restraint", _bind(restraint_bars_figure, data)))
    emu = emu_comparison(data)
    if data.references or _present(data, emu.configurations):
        tasks.append(("fig-emu", _bind(emu_figure, data, emu)))
    for comp in model_comparisons(data):
        tasks.append((f"fig-spring-{slug(comp.name)}", _bind(spring_model_figure, data, comp)))
    return tasks


def distinct_comparisons(data: ReportData) -> list[Comparison]:
    """Comparisons drawn as overlays and energy bars: not the EMU one (own section), with data present,
    and each set of configurations once (a protocol may list the same keys under §5.x and §5.7.2)."""
    seen: set[tuple[int, ...]] = set()
    out = []
    for comp in data.comparisons:
        key = tuple(sorted(comp.configurations))
        if is_emu(comp) or key in seen or not _present(data, comp.configurations):
            continue
        seen.add(key)
        out.append(comp)
    return out


def is_emu(comparison: Comparison) -> bool:
    """True for the EMU comparison of §5.6 (by parameter, name or section)."""
    return (
        comparison.parameter.lower() == "emu"
        or comparison.name.lower() == "emu"
        or comparison.section.strip("§ ") == "5.6"
    )


def emu_comparison(data: ReportData) -> Comparison:
    """The EMU-condition configurations (§5.6): the archive's comparison, else the thesis's keys 24-28."""
    for comp in data.comparisons:
        if is_emu(comp):
            return comp
    return Comparison("emu", "emu", "5.6", "EMU comparison", (24, 25, 26, 27, 28), from_archive=False)


def model_comparisons(data: ReportData) -> list[Comparison]:
    """The preload and stiffness comparisons whose configurations have spring fits (Figures 52-53)."""
    out = []
    for comp in distinct_comparisons(data):
        p = comp.parameter.lower()
        if ("preload" in p or "stiff" in p or "spring" in p) and any(
            c.spring is not None for c in _present(data, comp.configurations)
        ):
            out.append(comp)
    return out


def slug(text: str) -> str:
    """An HTML-id-safe version of `text`."""
    out = "".join(ch if ch.isalnum() else "-" for ch in text.lower()).strip("-")
    return out or "x"


def _bind(fn: Callable[..., str], *args: object) -> Callable[[], str]:
    return functools.partial(fn, *args)


_WORKER_TASKS: dict[str, Callable[[], str]] = {}


def _init_worker(data: ReportData) -> None:
    _WORKER_TASKS.clear()
    _WORKER_TASKS.update(_tasks(data))


def _run_one(task_id: str) -> tuple[str, str | None, str | None]:
    return _safe(task_id, _WORKER_TASKS[task_id])


def _safe(task_id: str, task: Callable[[], str]) -> tuple[str, str | None, str | None]:
    try:
        return task_id, task(), None
    except (ValueError, TypeError, IndexError, FloatingPointError) as exc:  # bad data never kills the report
        return task_id, None, f"{type(exc).__name__}: {exc}"


def render_figures(data: ReportData, workers: int | None = None) -> FigureSet:
    """Draw every figure of the report. `workers` > 1 draws on that many forked processes."""
    tasks = _tasks(data)
    if workers is None:
        workers = default_workers(len(tasks))
    results: list[tuple[str, str | None, str | None]] | None = None
    if workers > 1 and len(tasks) >= 8:
        _warm_up()
        # small chunks keep both workers busy: two-panel figures cost about twice a one-panel one
        results = map_in_processes(
            _run_one,
            [task_id for task_id, _ in tasks],
            workers,
            initializer=_init_worker,
            initargs=(data,),
            chunksize=4,
        )
    if results is None:
        results = [_safe(task_id, task) for task_id, task in tasks]
    images: dict[str, str] = {}
    missing: dict[str, str] = {}
    for task_id, uri, error in results:
        if uri is not None:
            images[task_id] = uri
        else:
            missing[task_id] = error or "not drawn"
    return FigureSet(images=images, missing=missing)


def _warm_up() -> None:
    """Create every canvas and render text once, so that forked workers inherit warm font caches."""
    for kind in _LAYOUTS:
        fig, axes = _axes(kind)
        for ax in axes:
            ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up")
            _style(ax, ANGLE_LABEL, TORQUE_LABEL, "warm-up 0123456789")
            _legend(ax)
        to_data_uri(fig)


def default_workers(n_tasks: int) -> int:
    """Worker processes for `n_tasks` figures: 2 when there are enough figures and cores, else 1."""
    if n_tasks < 40:
        return 1
    return max(1, min(2, os.cpu_count() or 1))
