"""One configuration group of an archive, for the report: trials, processed loops, energies and fits
(docs/archive.md)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import h5py
import numpy as np

from protocol_runner.archive.model_results import strings
from protocol_runner.report.h5read import (
    attr_bool,
    attr_float,
    attr_int,
    attr_str,
    decimate_for_plot,
    float_ds,
    read_only,
    read_record,
)
from protocol_runner.report.metrics import peak_of, range_of, slope_of
from protocol_runner.report.model import (
    BoucWenFit,
    BraceOffMatch,
    Configuration,
    ElementFit,
    ProcessedTrial,
    Recording,
    Trial,
)
from protocol_runner.report.settings_view import elements_from_json, settings_from_attrs


def _read_recording(grp: h5py.Group) -> Recording:
    return read_record(Recording, grp)


def _trial_numbers(trials: h5py.Group) -> list[tuple[int, str]]:
    numbered: list[tuple[int, str]] = []
    for name in trials:
        try:
            numbered.append((int(name), name))
        except ValueError:
            continue
    return sorted(numbered)


def read_configuration(name: str, grp: h5py.Group) -> Configuration:
    trials: list[Trial] = []
    angles: list[np.ndarray] = []
    torques: list[np.ndarray] = []
    raw_loaded = False
    trajectory_json = ""
    if "trials" in grp:
        trials_grp = grp["trials"]
        for number, tname in _trial_numbers(trials_grp):
            tgrp = trials_grp[tname]
            on = off = None
            sides = [side for side in ("brace_on", "brace_off") if side in tgrp]
            has_raw = bool(sides)
            # Only the first recorded trial's raw data is plotted (angle/torque vs time): reading and
            # decompressing the others would dominate the report's regeneration time.
            if has_raw and not raw_loaded:
                if "brace_on" in sides:
                    trajectory_json = attr_str(tgrp["brace_on"].attrs, "trajectory")
                on = _read_recording(tgrp["brace_on"]) if "brace_on" in sides else None
                off = _read_recording(tgrp["brace_off"]) if "brace_off" in sides else None
                raw_loaded = True
            processed = None
            if "processed" in tgrp:
                pgrp = tgrp["processed"]
                angle = float_ds(pgrp, "angle_deg")
                torque = float_ds(pgrp, "brace_torque_nm")
                n = min(angle.size, torque.size)
                angle, torque = angle[:n], torque[:n]
                angles.append(angle)
                torques.append(torque)
                processed = ProcessedTrial(
                    angle_deg=decimate_for_plot(angle),
                    brace_torque_nm=decimate_for_plot(torque),
                    subtraction=attr_str(pgrp.attrs, "subtraction", "equal_angle"),
                    filter_text=_filter_text(pgrp.attrs),
                    range_deg=range_of(angle, torque),
                    slope_nm_per_deg=slope_of(angle, torque),
                    peak_nm=peak_of(angle, torque),
                )
            trials.append(
                Trial(
                    number=number,
                    brace_on=on,
                    brace_off=off,
                    processed=processed,
                    recorded=has_raw,
                    match=brace_off_match(tgrp),
                )
            )
    angle_min, angle_max, slope = _summary(angles, torques)
    energy = float_ds(grp, "energy_loss_j")
    cycle_trial = float_ds(grp, "energy_cycle_trial")
    if cycle_trial.size != energy.size:
        cycle_trial = np.zeros(energy.size)
    return Configuration(
        name=name,
        **group_fields(name, grp.attrs, len(trials)),
        trials=tuple(trials),
        energy_loss_j=read_only(energy),
        energy_cycle_trial=read_only(cycle_trial),
        bouc_wen=_read_bouc_wen(grp["fits/bouc_wen"]) if "fits/bouc_wen" in grp else None,
        element_fit=_read_element_fit(grp["fits/elements"], name) if "fits/elements" in grp else None,
        angle_min_deg=angle_min,
        angle_max_deg=angle_max,
        torque_slope_nm_per_deg=slope,
        trajectory_json=trajectory_json,
    )


def brace_off_match(trial: h5py.Group) -> BraceOffMatch:
    """How well the brace-off twin of the trial stored in `trial` (`trials/<n>`) matched it: the kept
    scaling run's error and the runs (`brace_off/scaling`), whether it converged, and the clipped fraction
    (1 - `processed` @coverage). The report's per-trial table and trials.csv both read it here."""
    error: float | None = None
    runs: int | None = None
    converged: bool | None = None
    if "brace_off/scaling" in trial and "range_error_deg" in trial["brace_off/scaling"]:
        g = trial["brace_off/scaling"]
        errors = np.asarray(g["range_error_deg"][()], dtype=float)
        kept = attr_int(g.attrs, "kept_iteration", int(np.argmin(errors)) + 1)
        error, runs = float(errors[kept - 1]), int(errors.size)
        converged = attr_bool(g.attrs, "converged", False)
    clipped: float | None = None
    if "processed" in trial and "coverage" in trial["processed"].attrs:
        clipped = 1.0 - attr_float(trial["processed"].attrs, "coverage")
    return BraceOffMatch(error, runs, converged, clipped)


def group_fields(name: str, attrs: Mapping[str, Any], n_trials: int) -> dict[str, Any]:
    """The `Configuration` fields read from the group's own attributes `attrs` (its identity, status and
    settings), the group holding `n_trials` trials; every other field is read from its members."""
    return {
        "key": attr_int(attrs, "key", _key_from_name(name)),
        "run": attr_int(attrs, "run", 0),
        "set_name": attr_str(attrs, "set"),
        "condition": attr_str(attrs, "condition"),
        "profile": attr_str(attrs, "profile"),
        "status": attr_str(attrs, "status", "complete" if n_trials else "not run"),
        "n_trials_planned": attr_int(attrs, "n_trials", n_trials),
        "settings": settings_from_attrs(attrs, f"configuration {name}"),
    }


def with_group_attrs(cfg: Configuration, attrs: Mapping[str, Any]) -> Configuration:
    """`cfg` as read from a group whose own attributes are `attrs` (its members unchanged)."""
    return dataclasses.replace(cfg, **group_fields(cfg.name, attrs, len(cfg.trials)))


def _key_from_name(name: str) -> int:
    digits = "".join(ch for ch in name if ch.isdigit())
    return int(digits) if digits else 0


def _summary(angles: list[np.ndarray], torques: list[np.ndarray]) -> tuple[float, float, float]:
    """Angle range reached and least-squares torque-angle slope (N*m/deg) over all processed samples."""
    # accumulate the sums of the normal equations trial by trial (no concatenated copy)
    n = sx = sy = sxx = sxy = 0.0
    lo, hi = math.inf, -math.inf
    for angle, torque in zip(angles, torques, strict=True):
        ok = np.isfinite(angle) & np.isfinite(torque)
        if not ok.all():
            angle, torque = angle[ok], torque[ok]
        if angle.size == 0:
            continue
        n += angle.size
        sx += float(angle.sum())
        sy += float(torque.sum())
        sxx += float(np.einsum("i,i->", angle, angle))
        sxy += float(np.einsum("i,i->", angle, torque))
        lo, hi = min(lo, float(angle.min())), max(hi, float(angle.max()))
    if n < 2:
        return float("nan"), float("nan"), float("nan")
    denom = sxx - sx * sx / n
    slope = (sxy - sx * sy / n) / denom if denom > 1e-12 * max(sxx, 1.0) else float("nan")
    return lo, hi, slope


def _read_bouc_wen(grp: h5py.Group) -> BoucWenFit:
    models = grp.parent.get("models")
    if not isinstance(models, h5py.Group):
        return read_record(BoucWenFit, grp, parameter_identified=(), functionals=())
    values = [
        np.atleast_1d(np.asarray(models.attrs.get(k, []), dtype=np.float64))
        for k in ("functional_value", "functional_ci95_low", "functional_ci95_high")
    ]
    functionals = tuple(
        (name, unit, float(v), float(lo), float(hi))
        for name, unit, v, lo, hi in zip(
            strings(models, "functional"), strings(models, "functional_unit"), *values, strict=True
        )
    )
    flags = np.atleast_1d(np.asarray(models.attrs.get("bouc_wen_identified", []), dtype=np.int64))
    return read_record(
        BoucWenFit, grp, parameter_identified=tuple(bool(v) for v in flags), functionals=functionals
    )


def _filter_text(attrs: h5py.AttributeManager) -> str:
    """The processing filter as a reader wants it: type, order, cut-off in Hz ("" when not recorded)."""
    hz = attr_float(attrs, "filter_cutoff_hz")
    if not math.isfinite(hz):
        return ""
    kind = attr_str(attrs, "filter_type", "low-pass").capitalize()
    return f"{kind} low-pass, order {attr_int(attrs, 'filter_order', 0)}, cut-off {hz:.1f} Hz, zero-phase"


def _read_element_fit(grp: h5py.Group, name: str) -> ElementFit:
    a = grp.attrs
    parameters = tuple(
        (key, attr_float(a, key)) for key in sorted(a.keys()) if "." in key and not key.startswith(".")
    )
    elements_text = attr_str(a, "elements_json", "[]")
    return read_record(
        ElementFit,
        grp,
        applicable=attr_bool(a, "applicable", True),
        parameters=parameters,
        elements=elements_from_json(elements_text, f"configuration {name}: fits/elements"),
    )
