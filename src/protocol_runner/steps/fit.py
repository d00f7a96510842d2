"""Fit step: the generalised Bouc-Wen model (§6.2, Eq 19-25) on a configuration's processed, centred
loops, jointly over its trials, with leave-one-trial-out cross-validation when it has several trials.

It reads the loops the processing step stored and fits them with `analysis.service.fit_stored_loops`,
the function `--reprocess` reaches through `analyse_configuration`, so both give the same numbers. (The
device's elastic elements are fitted by the processing step, which has the branch curves at hand.)"""

from __future__ import annotations

import numpy as np

from ..analysis.model_comparison import compare_stored
from ..analysis.service import fit_stored_loops
from ..archive.model_results import comparison_fill, read_processed_trials
from ..archive.paths import configuration_name, trials_path
from ..archive.results import bouc_wen_fill, read_processed_loops
from ..protocol.plan_steps import FitStep
from ..protocol.processing import bouc_wen_settings, element_fit_enabled
from ..protocol.step_ids import step_id
from .context import StepContext, StepOutcome


def run(step: FitStep, ctx: StepContext) -> StepOutcome:
    if "bouc_wen" not in step.models:
        return StepOutcome(None, "no Bouc-Wen fit asked")
    with ctx.unit(step_id("process", key=step.configuration)) as f:
        loops = read_processed_loops(f[trials_path(step.configuration)])
        trials = (
            read_processed_trials(f[trials_path(step.configuration)])
            if element_fit_enabled(ctx.loaded)
            else []
        )
    device = ctx.trial_step(step.configuration).settings.device if element_fit_enabled(ctx.loaded) else None
    bouc_wen = fit_stored_loops(
        loops, bouc_wen_settings(ctx.loaded), list(device) if device is not None else None
    )
    result = bouc_wen.fit
    summary = f"Bouc-Wen RMSE {result.rmse_nm:.2f} N*m, R2 {result.r2:.3f}"
    if bouc_wen.cv_rmse_nm:
        summary += f", cross-validated RMSE {np.mean(bouc_wen.cv_rmse_nm):.2f} N*m"
    fill = bouc_wen_fill(configuration_name(step.configuration), bouc_wen)
    if device is not None:  # the model comparison: element model, reduced Dahl model, Bouc-Wen
        comparison = compare_stored(trials, device, bouc_wen)
        fill = comparison_fill(configuration_name(step.configuration), fill, comparison)
    return StepOutcome(fill, summary)
