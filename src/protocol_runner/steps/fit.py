"""Fit step: the generalised Bouc-Wen model (§6.2, Eq 19-25) on a configuration's processed, centred
loops, jointly over its trials, with leave-one-trial-out cross-validation when it has several trials.
(The physical spring model is fitted by the processing step, which has the branch curves at hand.)"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..analysis.loops import centred_loop, fit_loops
from ..archive.paths import configuration_name, trials_path
from ..archive.results import bouc_wen_fill
from ..models.bouc_wen import BoucWenFit
from ..protocol.plan import FitStep
from ..protocol.schema import BoucWenFitSpec
from ..protocol.step_ids import step_id
from .context import StepContext, StepOutcome

Loop = tuple[np.ndarray, np.ndarray]


def processed_trials(ctx: StepContext, step: FitStep) -> list[Loop]:
    """Each trial's processed (uncentred) angle and device torque, in trial order."""
    out = []
    with ctx.unit(step_id("process", key=step.configuration)) as f:
        trials = f[trials_path(step.configuration)]
        for n in sorted(trials, key=int):
            g = trials[n]["processed"]
            out.append((g["angle_deg"][:], g["brace_torque_nm"][:]))
    return out


def centred_segments(ctx: StepContext, step: FitStep) -> list[Loop]:
    return [centred_loop(a, t) for a, t in processed_trials(ctx, step)]


def fit_bouc_wen(
    segments: list[Loop],
    spec: BoucWenFitSpec,
    elements: tuple[list[Loop], Sequence[object] | None] | None = None,
) -> tuple[BoucWenFit, list[float]]:
    """The joint fit over a configuration's trials (with intervals), and leave-one-trial-out RMSEs when
    asked and possible (see :func:`..analysis.loops.fit_loops`).  With ``backbone: elements``,
    ``elements`` is (the processed uncentred trials, the device or None when the element fit is off);
    without it that backbone is ``g = 0``, recorded as such."""
    if spec.backbone == "elements" and elements is None:
        elements = ([], None)
    return fit_loops(
        segments,
        starts=spec.starts,
        cross_validated=spec.cross_validate,
        backbone_degree=spec.polynomial_degree,
        elements=elements if spec.backbone == "elements" else None,
    )


def elements_of(ctx: StepContext, step: FitStep) -> Sequence[object] | None:
    """The configuration's device when the element fit is enabled, else None (as the processing step)."""
    fits = ctx.loaded.protocol.fits
    enabled = getattr(fits, "elements", getattr(fits, "spring", None))
    if not (enabled and enabled.enabled):
        return None
    cfg_step = next(
        s
        for s in ctx.plan.steps
        if getattr(s, "configuration", None) == step.configuration and s.kind == "trial"
    )
    return list(cfg_step.settings.device)  # type: ignore[attr-defined]


def run(step: FitStep, ctx: StepContext) -> StepOutcome:
    if "bouc_wen" not in step.models:
        return StepOutcome(None, "no Bouc-Wen fit asked")
    spec = ctx.loaded.protocol.fits.bouc_wen
    raw = processed_trials(ctx, step)
    segments = [centred_loop(a, t) for a, t in raw]
    elements = (raw, elements_of(ctx, step)) if spec.backbone == "elements" else None
    result, cv = fit_bouc_wen(segments, spec, elements)
    name = configuration_name(step.configuration)
    fill = bouc_wen_fill(name, result, segments, cv)
    summary = f"Bouc-Wen RMSE {result.rmse_nm:.2f} N*m, R2 {result.r2:.3f}"
    if cv:
        summary += f", cross-validated RMSE {np.mean(cv):.2f} N*m"
    return StepOutcome(fill, summary)
