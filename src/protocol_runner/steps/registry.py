"""The step kinds, registered in one visible place: plan step kind -> the code that runs a step of it.

A kind's plan record (`protocol/plan_steps.py`) declares what it does, what it reads, whether it uses the
rig and whether it runs in an analysis worker; its entry here names the function that runs it, for one
driven joint or several. Each function takes the step and the StepContext and returns a StepOutcome (how to write its unit). The report step is the
runner's own (it consolidates the archive first): see session/runner.py.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .context import StepContext, StepOutcome

StepFunction = Callable[[Any, StepContext], StepOutcome]


@dataclass(frozen=True)
class StepKind:
    """How a step of a kind runs: `run`, a function, or the name "module.function" of one of this
    package's modules, imported when a step of the kind first runs: so the session process never loads
    what only the analysis workers run (the processing and the fits: scipy's signal, optimisation and
    statistics)."""

    run: str | StepFunction

    def function(self) -> StepFunction:
        """The function that runs a step of this kind."""
        return step_function(self.run) if isinstance(self.run, str) else self.run


STEP_KINDS: dict[str, StepKind] = {
    "calibration_check": StepKind("calibration_check.run"),
    "operator_checklist": StepKind("checklist.run"),
    "trial": StepKind("trial.run"),
    "process": StepKind("process.run"),
    "fit": StepKind("fit.run"),
    "compare": StepKind("compare.run"),
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
    return entry.function()
