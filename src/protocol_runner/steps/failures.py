"""An analysis that cannot be done reaches the user as one message naming configuration, trial and step.

When the recorded data or the processing settings do not allow an analysis, it raises `AnalysisError`;
`run_step` turns that into `AnalysisStepFailed`, whose message says where it happened and what the user
can do. Redoing the step on the same data fails the same way, so the runner adds no "resumable" line.
"""

from __future__ import annotations

import re

from ..analysis.validation import AnalysisError
from ..errors import InvalidInput
from ..protocol.plan_steps import FitStep, ProcessStep, Step, TrialStep
from .context import StepContext, StepOutcome
from .registry import run_function


class AnalysisStepFailed(InvalidInput):
    """An analysis step failed on the recorded data (exit 2); a resume alone would fail the same way."""

    resumable = False


def run_step(step: Step, ctx: StepContext) -> StepOutcome:
    """Run one step; an `AnalysisError` becomes `AnalysisStepFailed` naming the step and what to do."""
    try:
        return run_function(step.kind)(step, ctx)
    except AnalysisError as exc:
        raise AnalysisStepFailed(explain(step, exc.message, ctx)) from None


def explain(step: Step, message: str, ctx: StepContext) -> str:
    session = ctx.units_dir.parent
    if isinstance(step, TrialStep):
        return (
            f"configuration {step.configuration}, trial {step.trial} (brace {step.brace}), step {step.id}: "
            f"{message}\nEvery finished recording is kept in {session}. This brace-off trial follows the "
            f"brace-on recording {step.twin}: check it (run-protocol --report {session} shows it). A resume "
            "redoes this trial; if that recording is at fault it fails the same way."
        )
    where = f"step {step.id}"
    if isinstance(step, (ProcessStep, FitStep)):
        trial = re.search(r"\btrial (\d+)\b", message)
        which = f"trial {trial.group(1)}" if trial else "all its trials"
        where = f"configuration {step.configuration}, {which}, {where}"
    return (
        f"{where}: {message}\n"
        f"Every recording is kept in {session}; a resume would redo this step on the same data and fail "
        f"the same way. Look at the raw data (run-protocol --report {session}). If the processing "
        f"settings do not suit these data, change `processing` in {ctx.loaded.path} and resume with "
        f"--force, or re-analyse the archive: run-protocol --report {session} --reprocess --protocol-file "
        "FIXED.yaml"
    )
