"""The step kinds, registered in one visible place: plan step kind -> the code that runs a step of it.

A kind's plan record (`protocol/plan_steps.py`) declares what it does, what it reads, whether it uses the
rig and whether it runs in an analysis worker; its entry here is the function that runs it, for one driven
joint or several, or its name "module.function" in this package, imported when a step of the kind first
runs: so the session process never loads what only the analysis workers run (the processing and the fits:
scipy's signal, optimisation and statistics). Each function takes the step and the StepContext and returns
a StepOutcome (how to write its unit). The report step is the runner's own (it consolidates the archive
first): see session/runner.py.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from .context import StepContext, StepOutcome

StepFunction = Callable[[Any, StepContext], StepOutcome]

STEP_KINDS: dict[str, str | StepFunction] = {
    "calibration_check": "calibration_check.run",
    "operator_checklist": "checklist.run",
    "trial": "trial.run",
    "process": "process.run",
    "fit": "fit.run",
    "compare": "compare.run",
}


def step_function(name: str) -> StepFunction:
    """The function `name` ("module.function") of this package, importing its module."""
    module, function = name.split(".")
    found: StepFunction = getattr(importlib.import_module(f"{__package__}.{module}"), function)
    return found


def run_function(kind: str) -> StepFunction:
    """The function that runs a step of `kind` (`LookupError` for a kind nobody registered)."""
    entry = STEP_KINDS.get(kind)
    if entry is None:
        raise LookupError(f"no step kind {kind!r} is registered (steps/registry.py)")
    return step_function(entry) if isinstance(entry, str) else entry
