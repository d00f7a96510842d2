"""One configuration group of an archive, for the report: per joint (`archive.paths.joint_groups`), its
trials, processed loops, energies and fits, and the energy of all joints together (docs/archive.md)."""

from __future__ import annotations

import math
from typing import Any

import h5py
import numpy as np

from protocol_runner.archive.model_results import strings
from protocol_runner.archive.paths import JOINTS, joint_groups
from protocol_runner.report.h5read import (
    attr_bool,
    attr_float,
    attr_int,
    attr_str,
    decimate_for_plot,
    decode,
    float_ds,
    read_only,
    read_record,
)
from protocol_runner.report.headline import peak_of, range_of, slope_of
from protocol_runner.report.model import (
    BoucWenFit,
    BraceOffMatch,
    Configuration,
    ElementFit,
    JointsTotal,
    ProcessedTrial,
    Recording,
    Trial,
)
from protocol_runner.report.settings_view import elements_from_json, settings_from_attrs


def _read_recording(joint: h5py.Group, shared: h5py.Group) -> Recording:
    """One joint's recording: its own group `joint` (the brace group itself for a single-joint archive),
    with the time base and the output loop's lateness of the trial's `shared` brace group where the joint's
    group does not repeat them."""
    given: dict[str, Any] = {
        name: decimate_for_plot(float_ds(shared, name))
        for name in ("time_s", "command_time_s")
        if name not in joint
    }
    if "tick_lateness_p99_s" not in joint.attrs:
        given["tick_lateness_p99_s"] = attr_float(shared.attrs, "tick_lateness_p99_s")
    return read_record(Recording, joint, **given)


def _trial_numbers(*trials: h5py.Group | None) -> list[tuple[int, str]]:
    """(number, name) of every trial group (a name of digits) under any of `trials`, in number order."""
    return sorted({(int(name), name) for group in trials for name in group or () if name.isdecimal()})


def read_configuration(
    name: str, grp: h5py.Group, archive_joints: str
) -> tuple[list[Configuration], JointsTotal | None]:
    """Configuration group `grp` (`name`) as one `Configuration` per joint, in channel order, and the energy
    of all its joints together when it drives several. `archive_joints` is the root attribute `joint`: it
    names the joint of a group written without a `joints/` level (`archive.paths.joint_groups`)."""
    parts: list[tuple[str, h5py.Group | None]] = list(joint_groups(grp, archive_joints))
    if JOINTS not in grp and JOINTS in grp.attrs:  # several joints, none processed yet: their recordings
        parts = [(str(j), None) for j in decode(np.atleast_1d(grp.attrs[JOINTS]))]
    configs = [_read_joint(name, grp, joint, results, archive_joints) for joint, results in parts]
    total = None
    if "total_energy_loss_j" in grp and len(configs) > 1:  # one joint: its own energy is the total
        energy = float_ds(grp, "total_energy_loss_j")
        total = JointsTotal(
            key=configs[0].key,
            energy_loss_j=read_only(energy),
            energy_cycle_trial=read_only(_cycle_trials(grp, "total_energy_cycle_trial", energy.size)),
        )
    return configs, total


def _cycle_trials(grp: h5py.Group, name: str, n_cycles: int) -> np.ndarray:
    """The trial of each cycle (dataset `name`), zeros when it does not match the `n_cycles` energies."""
    cycle_trial = float_ds(grp, name)
    return cycle_trial if cycle_trial.size == n_cycles else np.zeros(n_cycles)


def _read_joint(
    name: str, grp: h5py.Group, joint: str, results: h5py.Group | None, archive_joints: str
) -> Configuration:
    """Joint `joint`'s part of configuration group `grp`: its recordings from the trial groups `grp/trials`,
    its processing from `results` (`grp/joints/<joint>`, or `grp` itself for a single-joint archive; None
    before it is processed)."""
    trials: list[Trial] = []
    angles: list[np.ndarray] = []
    torques: list[np.ndarray] = []
    raw_loaded = False
    trajectory_json = ""
    raw_trials = grp.get("trials")
    processed_trials = results.get("trials") if results is not None else None
    for number, tname in _trial_numbers(raw_trials, processed_trials):
        tgrp = raw_trials.get(tname) if raw_trials is not None else None
        sides = {
            side: part
            for side in ("brace_on", "brace_off")
            if tgrp is not None and side in tgrp
            if (part := dict(joint_groups(tgrp[side], archive_joints)).get(joint)) is not None
        }
        on = off = None
        # Only the first recorded trial's raw data is plotted (angle/torque vs time): reading and
        # decompressing the others would dominate the report's regeneration time.
        if sides and not raw_loaded:
            assert tgrp is not None
            if "brace_on" in sides:
                trajectory_json = attr_str(sides["brace_on"].attrs, "trajectory")
                on = _read_recording(sides["brace_on"], tgrp["brace_on"])
            if "brace_off" in sides:
                off = _read_recording(sides["brace_off"], tgrp["brace_off"])
            raw_loaded = True
        ptrial = processed_trials.get(tname) if processed_trials is not None else None
        pgrp = ptrial.get("processed") if ptrial is not None else None
        processed = None
        if pgrp is not None:
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
                recorded=bool(sides),
                match=brace_off_match(sides.get("brace_off"), pgrp),
            )
        )
    angle_min, angle_max = _angle_span(angles, torques)
    fits = results if results is not None else {}
    energy = float_ds(results, "energy_loss_j") if results is not None else read_only(np.empty(0))
    cycle_trial = _cycle_trials(results, "energy_cycle_trial", energy.size) if results is not None else energy
    attrs = grp.attrs
    digits = "".join(ch for ch in name if ch.isdigit())
    return Configuration(
        name=name,
        key=attr_int(attrs, "key", int(digits) if digits else 0),
        joint=joint,
        run=attr_int(attrs, "run", 0),
        set_name=attr_str(attrs, "set"),
        condition=attr_str(attrs, "condition"),
        profile=attr_str(attrs, "profile"),
        status=attr_str(attrs, "status", "complete" if trials else "not run"),
        n_trials_planned=attr_int(attrs, "n_trials", len(trials)),
        settings=settings_from_attrs(attrs, f"configuration {name}"),
        trials=tuple(trials),
        energy_loss_j=read_only(energy),
        energy_cycle_trial=read_only(cycle_trial),
        bouc_wen=_read_bouc_wen(fits["fits/bouc_wen"]) if "fits/bouc_wen" in fits else None,
        element_fit=_read_element_fit(fits["fits/elements"], name) if "fits/elements" in fits else None,
        angle_min_deg=angle_min,
        angle_max_deg=angle_max,
        trajectory_json=trajectory_json,
    )


def brace_off_match(brace_off: h5py.Group | None, processed: h5py.Group | None) -> BraceOffMatch:
    """How well one joint's brace-off twin matched its trial: the kept scaling run's error and the runs
    (`scaling/` of the joint's brace-off group `brace_off`), whether it converged, and the clipped fraction
    (1 - the joint's `processed` @coverage). The report's per-trial table and trials.csv both read it
    here."""
    error: float | None = None
    runs: int | None = None
    converged: bool | None = None
    if brace_off is not None and "scaling" in brace_off and "range_error_deg" in brace_off["scaling"]:
        g = brace_off["scaling"]
        errors = np.asarray(g["range_error_deg"][()], dtype=float)
        kept = attr_int(g.attrs, "kept_iteration", int(np.argmin(errors)) + 1)
        error, runs = float(errors[kept - 1]), int(errors.size)
        converged = attr_bool(g.attrs, "converged", False)
    clipped: float | None = None
    if processed is not None and "coverage" in processed.attrs:
        clipped = 1.0 - attr_float(processed.attrs, "coverage")
    return BraceOffMatch(error, runs, converged, clipped)


def _angle_span(angles: list[np.ndarray], torques: list[np.ndarray]) -> tuple[float, float]:
    """The lowest and highest processed angle reached (deg) over the samples with a finite angle and torque;
    NaN with fewer than two such samples."""
    reached = [a[np.isfinite(a) & np.isfinite(t)] for a, t in zip(angles, torques, strict=True)]
    reached = [a for a in reached if a.size]
    if sum(a.size for a in reached) < 2:
        return math.nan, math.nan
    return min(float(a.min()) for a in reached), max(float(a.max()) for a in reached)


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
