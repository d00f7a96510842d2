"""The archive's result groups: what processing, fits and comparisons write, and the raw recordings
they read (layout in docs/archive.md).

Shared by the processing steps and `--reprocess`, so that both write the same groups.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from .h5util import SIGNAL, put_attrs
from .paths import CONFIGURATIONS, FITS, PROCESSED, TRIALS, put_dataset

if TYPE_CHECKING:  # the session writes trial units through this module: it never loads the analysis
    from ..analysis.element_fit import ElementFit
    from ..analysis.pipeline import Recording
    from ..analysis.processing_settings import ProcessingSettings
    from ..analysis.service import BoucWenResult, ConfigurationAnalysis
    from ..models.bouc_wen.records import BoucWenFit

#: Writes one step's results into an open unit file.
Fill = Callable[[h5py.File], None]

#: At most this many points per trial of the Bouc-Wen model curve are stored for the report.
PLOT_POINTS_PER_TRIAL = 2000
BACKBONE_GRID_POINTS = 201  # samples of an elements backbone g over the fitted (centred) angle range


def read_recording(g: h5py.Group) -> Recording:
    """A trial's raw recording (`trials/<n>/brace_<b>`, or a joint's `joints/<joint>` in it)."""
    from ..analysis.pipeline import Recording  # read by the processing, which has loaded it

    return Recording(
        time_s=g["time_s"][()],
        angle_deg=g["angle_deg"][()],
        torque_nm=g["torque_nm"][()],
        command_deg=g["command_deg"][()],
        command_time_s=g["command_time_s"][()],
    )


def read_processed_loops(trials: h5py.Group) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each trial's stored processed loop (`<n>/processed`: `angle_deg`, `brace_torque_nm`) under a
    `trials` group, in trial order: the Bouc-Wen fit's input."""
    loops = []
    for n in sorted(trials, key=int):
        g = trials[n][PROCESSED]
        loops.append((g["angle_deg"][()], g["brace_torque_nm"][()]))
    return loops


def processed_fill(name: str, analysis: ConfigurationAnalysis, settings: ProcessingSettings) -> Fill:
    """`trials/<n>/processed` of each trial (the stored loops of `analysis`), the configuration's energy
    per cycle and, when the device was given, `fits/elements`, under `configurations/<name>`."""
    result = analysis.processed

    def fill(f: h5py.File) -> None:
        cfg = f.require_group(f"{CONFIGURATIONS}/{name}")
        for t, s in zip(result.trials, analysis.stored, strict=True):
            g = cfg.require_group(f"{TRIALS}/{t.trial}").create_group(PROCESSED)
            put_dataset(g, "processed", "time_s", s.time_s)
            put_dataset(g, "processed", "angle_deg", s.angle_deg, dtype=SIGNAL)
            put_dataset(g, "processed", "brace_torque_nm", s.brace_torque_nm, dtype=SIGNAL)
            put_attrs(
                g,
                "processed",
                {
                    "sample_rate_hz": s.sample_rate_hz,
                    "decimation": s.decimation,
                    "energy_cycles_j": [float(e) for e in t.energy_j],
                    "transition_index0_on": int(t.transition_index_on),
                    "transition_index0_off": int(t.transition_index_off),
                    "subtraction": settings.subtraction,
                    "filter": json.dumps(settings.filter_description(s.input_rate_hz)),
                    # the zero-phase low-pass filter ran at the input rate, before the decimation
                    "filter_type": settings.filter_kind,
                    "filter_order": int(settings.filter_order),
                    "filter_cutoff_hz": float(settings.filter_cutoff / (2.0 * s.input_interval_s)),
                    "coverage": float(t.coverage),
                },
            )
        put_dataset(cfg, "configuration", "energy_loss_j", result.energy_loss_j)
        put_dataset(cfg, "configuration", "energy_cycle_trial", result.energy_cycle_trial)
        put_attrs(
            cfg["energy_loss_j"],
            "energy_loss",
            {"mean_j": result.energy.mean_j, "std_j": result.energy.std_j},
        )
        if result.elements is not None:
            element_fit_fill(cfg.require_group(FITS), result.elements)

    return fill


def element_fit_fill(fits: h5py.Group, fit: ElementFit) -> None:
    """`fits/elements` (docs/archive.md): the fit of the device's elastic elements."""
    g = fits.create_group("elements")
    attrs: dict[str, Any] = {
        "applicable": bool(fit.applicable),
        "reason": fit.reason,
        "target": fit.target,
        "rmse_nm": float(fit.rmse_nm),
        "rmse_all_samples_nm": float(fit.rmse_all_samples_nm),
        "elements_json": json.dumps([e.to_json() for e in fit.elements]),
    }
    fitted = {f"{element}.{param}": float(value) for element, param, value in fit.fitted}
    put_attrs(g, "elements", attrs, dynamic=fitted)
    put_dataset(g, "elements", "angle_deg", fit.curve_angle_deg, dtype=SIGNAL)
    put_dataset(g, "elements", "torque_nm", fit.curve_torque_nm, dtype=SIGNAL)
    put_dataset(g, "elements", "model_torque_nm", fit.model_torque_nm)
    _interim_spring_group(fits, fit)


def _interim_spring_group(fits: h5py.Group, fit: ElementFit) -> None:
    """The former `fits/spring` group (docs/archive.md: INTERIM until the report reads `fits/elements`),
    for a device with exactly one lever spring."""
    springs = [e for e in fit.elements if e.type == "lever_spring"]
    if len(springs) != 1 and fit.applicable:
        return
    s = springs[0] if springs else None
    fitted = {param: value for element, param, value in fit.fitted if s is not None and element == s.name}
    g = fits.create_group("spring")
    put_attrs(
        g,
        "spring",
        {
            "applicable": bool(fit.applicable),
            "reason": fit.reason,
            "max_preload_mm": float(fitted.get("max_preload_mm", math.nan)),
            "zero_offset_deg": float(fitted.get("zero_offset_deg", math.nan)),
            "rmse_nm": float(fit.rmse_nm),
            "rmse_all_samples_nm": float(fit.rmse_all_samples_nm),
            "stiffness_n_per_mm": float(s.number("stiffness_n_per_mm")) if s is not None else math.nan,
            "preload_position": int(s.number("preload_index")) if s is not None else 0,
            "target": fit.target,
        },
    )
    put_dataset(g, "spring", "angle_deg", fit.curve_angle_deg, dtype=SIGNAL)
    put_dataset(g, "spring", "torque_nm", fit.curve_torque_nm, dtype=SIGNAL)
    put_dataset(g, "spring", "model_torque_nm", fit.model_torque_nm)


def backbone_attrs(result: BoucWenFit) -> dict[str, object]:
    """What ``g`` in torque = g(angle) + z is: ``none`` (g = 0, with the reason in ``backbone_note`` when
    one was asked for), ``polynomial`` (its coefficients) or ``elements`` (the device's elastic elements
    with their fitted parameters; ``g`` sampled on ``backbone_grid_angle_deg``)."""
    from ..models.bouc_wen.backbone import Backbone, FixedBackbone  # written by the fit, which has loaded it

    bb = result.backbone
    out: dict[str, object] = {
        "backbone": "none",
        "backbone_note": "",
        "backbone_coef": [],
        "backbone_angle_scale_deg": math.nan,
    }
    if isinstance(bb, Backbone):
        out["backbone"] = "polynomial"
        out["backbone_coef"] = [float(c) for c in bb.coef]
        out["backbone_angle_scale_deg"] = bb.angle_scale_deg
    elif isinstance(bb, FixedBackbone):
        out["backbone"] = bb.kind
        out["backbone_note"] = bb.note
    if isinstance(bb, FixedBackbone) and bb.kind != "none":
        grid = np.linspace(-result.angle_scale_deg, result.angle_scale_deg, BACKBONE_GRID_POINTS)
        out["backbone_grid_angle_deg"] = [float(v) for v in grid]
        out["backbone_grid_torque_nm"] = [float(v) for v in bb(grid)]
    return out


def bouc_wen_fill(name: str, bouc_wen: BoucWenResult) -> Fill:
    """`fits/bouc_wen` of `configurations/<name>`: the fit, its evidence, and the fitted loops with the
    model's torque, decimated for plotting."""
    result = bouc_wen.fit
    p = result.params
    std = np.asarray(result.param_std, dtype=np.float64)
    cv = bouc_wen.cv_rmse_nm
    energy = bouc_wen.energy
    angles, torques, models = [], [], []
    for (x, y), z in zip(bouc_wen.segments, bouc_wen.model_torque_nm, strict=True):
        stride = max(1, len(x) // PLOT_POINTS_PER_TRIAL)
        angles.append(x[::stride])
        torques.append(y[::stride])
        models.append(z[::stride])

    def fill(f: h5py.File) -> None:
        g = f.require_group(f"{CONFIGURATIONS}/{name}/{FITS}").create_group("bouc_wen")
        put_attrs(
            g,
            "bouc_wen",
            {
                "A": float(p.A),
                "n": float(p.n),
                "beta": [float(b) for b in p.beta],
                "rmse_nm": float(result.rmse_nm),
                "r2": float(result.r2),
                "A_std": float(std[0]),
                "n_std": float(std[1]),
                "beta_std": [float(v) for v in std[2:8]],
                "cv_rmse_nm": [float(v) for v in cv],
                "n_starts": int(result.n_starts),
                "converged": bool(result.converged),
                "diverged": bool(result.diverged),
                # the evidence that lets a modeller judge the fit
                "scheme": result.scheme,
                "rmse_refined_nm": float(result.rmse_refined_nm),
                "optimizer_status": int(result.status),
                "optimizer_message": result.message,
                "start_rmse_nm": [float(v) for v in result.start_rmse_nm],
                "cost_spread": float(result.cost_spread),
                "n_interval": [float(v) for v in result.n_interval],
                "param_interval_low": [float(v) for v in result.param_interval_low],
                "param_interval_high": [float(v) for v in result.param_interval_high],
                "weakly_identified": bool(result.weakly_identified),
                "weak_reasons": "; ".join(result.weak_reasons),
                "model_energy_j": float(energy.model_j),
                "data_energy_j": float(energy.data_j),
                "model_dissipates": bool(energy.model_dissipates),
                **backbone_attrs(result),
            },
        )
        put_dataset(g, "bouc_wen", "angle_deg", np.concatenate(angles))
        put_dataset(g, "bouc_wen", "torque_nm", np.concatenate(torques))
        put_dataset(g, "bouc_wen", "model_torque_nm", np.concatenate(models))
        put_dataset(g, "bouc_wen", "segment_lengths", [len(a) for a in angles])

    return fill


def comparison_values(configs: Sequence[h5py.Group]) -> dict[str, list[Any]]:
    """Energy per cycle (mean, sample std, count) and the largest processed angle of each configuration
    group, in order. Used by the session's step and by `--reprocess`, so both give the same numbers.
    A multi-joint configuration (no `energy_loss_j` of its own) is compared by its total over the joints
    (`total_energy_loss_j`, docs/archive.md "Several joints")."""
    means, stds, counts, max_angles = [], [], [], []
    for cfg in configs:
        name = "energy_loss_j" if "energy_loss_j" in cfg else "total_energy_loss_j"
        e = cfg[name][:] if name in cfg else np.zeros(0)
        means.append(float(np.mean(e)) if e.size else float("nan"))
        stds.append(float(np.std(e, ddof=1)) if e.size > 1 else float("nan"))
        counts.append(int(e.size))
        angles = [
            cfg[f"{TRIALS}/{n}/{PROCESSED}/angle_deg"][:]
            for n in cfg.get(TRIALS, {})
            if PROCESSED in cfg[f"{TRIALS}/{n}"]
        ]
        max_angles.append(max((float(np.max(a)) for a in angles if a.size), default=float("nan")))
    return {
        "energy_mean_j": means,
        "energy_std_j": stds,
        "energy_cycles": counts,
        "max_angle_deg": max_angles,
    }
