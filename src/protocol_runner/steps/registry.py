"""The step kinds, registered in one visible place: plan step kind -> the function that runs it.

Each function takes the step and the StepContext and returns a StepOutcome (how to write its unit).
The report step is the runner's own (it consolidates the archive first): see session/runner.py.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from .context import StepContext, StepOutcome

StepFunction = Callable[[Any, StepContext], StepOutcome]


#: Step kind -> the function that runs it ("module.function" of this package) ...
ONE_JOINT = {
    "calibration_check": "calibration_check.run",
    "operator_checklist": "checklist.run",
    "trial": "trial.run",
    "process": "process.run",
    "fit": "fit.run",
    "compare": "compare.run",
}
#: ... and where a protocol with `joints:` drives several joints, for the kinds that differ
SEVERAL_JOINTS = {
    "calibration_check": "multi_calibration.run",
    "trial": "multi_trial.run_trial",
    "process": "multi_trial.run_process",
    "fit": "multi_trial.run_fit",
}


def step_function(name: str) -> StepFunction:
    """The function `name` ("module.function") of this package, importing its module: a step kind's module
    is imported when a step of that kind first runs, so the session process never loads what only the
    analysis workers run (the processing and the fits: scipy's signal, optimisation and statistics)."""
    module, function = name.split(".")
    found: StepFunction = getattr(importlib.import_module(f"{__package__}.{module}"), function)
    return found


def _by_joints(single: str, several: str) -> StepFunction:
    """One joint's step function, or the multi-joint one for a protocol with `joints:`."""

    def run(step: Any, ctx: StepContext) -> StepOutcome:
        return step_function(several if ctx.loaded.protocol.multi_joint else single)(step, ctx)

    return run


STEP_KINDS: dict[str, StepFunction] = {
    kind: _by_joints(name, SEVERAL_JOINTS.get(kind, name)) for kind, name in ONE_JOINT.items()
}
