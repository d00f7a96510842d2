"""The step kinds, registered in one visible place: plan step kind -> the function that runs it.

Each function takes the step and the StepContext and returns a StepOutcome (how to write its unit).
The report step is the runner's own (it consolidates the archive first): see session/runner.py.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import calibration_check, checklist, compare, fit, multi_calibration, multi_trial, process, trial
from .context import StepContext, StepOutcome

StepFunction = Callable[[Any, StepContext], StepOutcome]


def _by_joints(single: StepFunction, several: StepFunction) -> StepFunction:
    """One joint's step function, or the multi-joint one for a protocol with `joints:`."""

    def run(step: Any, ctx: StepContext) -> StepOutcome:
        return (several if ctx.loaded.protocol.multi_joint else single)(step, ctx)

    return run


STEP_KINDS: dict[str, StepFunction] = {
    "calibration_check": _by_joints(calibration_check.run, multi_calibration.run),
    "operator_checklist": checklist.run,
    "trial": _by_joints(trial.run, multi_trial.run_trial),
    "process": _by_joints(process.run, multi_trial.run_process),
    "fit": _by_joints(fit.run, multi_trial.run_fit),
    "compare": compare.run,
}
