"""The step kinds, registered in one visible place: plan step kind -> the function that runs it.

Each function takes the step and the StepContext and returns a StepOutcome (how to write its unit).
The report step is the runner's own (it consolidates the archive first): see session/runner.py.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import calibration_check, checklist, compare, fit, process, trial
from .context import StepContext, StepOutcome

StepFunction = Callable[[Any, StepContext], StepOutcome]

STEP_KINDS: dict[str, StepFunction] = {
    "calibration_check": calibration_check.run,
    "operator_checklist": checklist.run,
    "trial": trial.run,
    "process": process.run,
    "fit": fit.run,
    "compare": compare.run,
}
