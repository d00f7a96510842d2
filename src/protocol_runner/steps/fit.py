"""Fit step: the generalised Bouc-Wen model (§6.2, Eq 19-25) on a configuration's processed, centred
loops, jointly over its trials, with leave-one-trial-out cross-validation when it has several trials.
(The physical spring model is fitted by the processing step, which has the branch curves at hand.)"""

from __future__ import annotations

import numpy as np

from ..analysis.loops import centred_loop, fit_loops
from ..archive.paths import configuration_name, trials_path
from ..archive.results import bouc_wen_fill
from ..models.bouc_wen import BoucWenFit
from ..protocol.plan import FitStep
from ..protocol.schema import BoucWenFitSpec
from ..protocol.step_ids import step_id
from .context import StepContext, StepOutcome


def centred_segments(ctx: StepContext, step: FitStep) -> list[tuple[np.ndarray, np.ndarray]]:
    segments = []
    with ctx.unit(step_id("process", key=step.configuration)) as f:
        trials = f[trials_path(step.configuration)]
        for n in sorted(trials, key=int):
            g = trials[n]["processed"]
            segments.append(centred_loop(g["angle_deg"][:], g["brace_torque_nm"][:]))
    return segments


def fit_bouc_wen(
    segments: list[tuple[np.ndarray, np.ndarray]], spec: BoucWenFitSpec
) -> tuple[BoucWenFit, list[float]]:
    """The joint fit over a configuration's trials (with intervals), and leave-one-trial-out RMSEs when
    asked and possible (see :func:`..analysis.loops.fit_loops`)."""
    return fit_loops(
        segments,
        starts=spec.starts,
        cross_validated=spec.cross_validate,
        backbone_degree=spec.polynomial_degree,
    )


def run(step: FitStep, ctx: StepContext) -> StepOutcome:
    if "bouc_wen" not in step.models:
        return StepOutcome(None, "no Bouc-Wen fit asked")
    segments = centred_segments(ctx, step)
    result, cv = fit_bouc_wen(segments, ctx.loaded.protocol.fits.bouc_wen)
    name = configuration_name(step.configuration)
    fill = bouc_wen_fill(name, result, segments, cv)
    summary = f"Bouc-Wen RMSE {result.rmse_nm:.2f} N*m, R2 {result.r2:.3f}"
    if cv:
        summary += f", cross-validated RMSE {np.mean(cv):.2f} N*m"
    return StepOutcome(fill, summary)
