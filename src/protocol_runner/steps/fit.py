"""Fit step: the generalised Bouc-Wen model (§6.2, Eq 19-25) on each fitted joint's processed, centred
loops of a configuration, jointly over its trials, with leave-one-trial-out cross-validation when it has
several trials; with the element fit on, also the joint's model comparison (`fits/element_model`,
`fits/models`). It fits the loops the processing step stored with `analysis.service.fit_stored_loops`,
which `--reprocess` reaches too, so both give the same numbers."""

from __future__ import annotations

import h5py
import numpy as np

from ..analysis.model_comparison import compare_stored
from ..analysis.service import fit_stored_loops
from ..archive.model_results import comparison_fill, read_processed_trials
from ..archive.paths import TRIALS, configuration_name, configuration_path, joint_path
from ..archive.results import Fill, bouc_wen_fill, read_processed_loops
from ..protocol.plan_steps import FitStep
from ..protocol.processing import bouc_wen_settings
from ..protocol.step_ids import step_id
from .context import StepContext, StepOutcome
from .process import fitted_joints, joint_devices
from .recording import joint_trajectories


def run(step: FitStep, ctx: StepContext) -> StepOutcome:
    if "bouc_wen" not in step.models:
        return StepOutcome(None, "no Bouc-Wen fit asked")
    cfg_step = ctx.trial_step(step.configuration)
    name = configuration_name(step.configuration)
    joints = [j for j, _ in joint_trajectories(cfg_step, ctx)]
    fitted = fitted_joints(cfg_step, joints)
    devices = joint_devices(ctx, cfg_step, joints)
    with ctx.unit(step_id("process", key=step.configuration)) as f:
        trials = {j: f[f"{joint_path(configuration_path(step.configuration), j)}/{TRIALS}"] for j in fitted}
        loops = {j: read_processed_loops(g) for j, g in trials.items()}
        stored = {j: read_processed_trials(g) for j, g in trials.items() if devices[j] is not None}
    settings = bouc_wen_settings(ctx.loaded)
    fills: list[Fill] = []
    parts: list[str] = []
    for joint in fitted:
        device = devices[joint]
        bouc_wen = fit_stored_loops(loops[joint], settings, list(device) if device is not None else None)
        fill_one = bouc_wen_fill(joint_path(name, joint), bouc_wen)
        if device is not None:  # the model comparison: element model, reduced Dahl model, Bouc-Wen
            fill_one = comparison_fill(
                joint_path(name, joint), fill_one, compare_stored(stored[joint], device, bouc_wen)
            )
        fills.append(fill_one)
        who = f"{joint} " if len(joints) > 1 else "Bouc-Wen "
        text = f"{who}RMSE {bouc_wen.fit.rmse_nm:.2f} N*m, R2 {bouc_wen.fit.r2:.3f}"
        if bouc_wen.cv_rmse_nm and len(joints) == 1:
            text += f", cross-validated RMSE {np.mean(bouc_wen.cv_rmse_nm):.2f} N*m"
        parts.append(text)

    def fill(f: h5py.File) -> None:
        for one in fills:
            one(f)

    return StepOutcome(fill, "; ".join(parts))
