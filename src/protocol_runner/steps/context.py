"""What every step's `run(step, ctx)` receives: the protocol, the plan, the bench (rig), the operator, the
units, the journal."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import h5py

from ..analysis.processing_settings import ProcessingSettings
from ..archive.results import Fill
from ..archive.units import open_unit
from ..errors import UserError
from ..events import NULL_PUBLISHER, Publisher
from ..hardware.rig import Rig
from ..protocol.loaded import LoadedProtocol
from ..protocol.plan_steps import Plan, TrialStep
from ..protocol.settings import Settings
from .operator import Operator


class JournalView(Protocol):
    """What steps read from the session journal: the units already complete, by step id."""

    @property
    def units(self) -> Mapping[str, object]: ...


class Bench(Protocol):
    """The rig plus what the operator does by hand (fitting the brace); simulated or real."""

    rig: Rig
    mode: str

    def begin_step(self, step_id: str) -> None: ...

    def fit_brace(self, settings: Settings | None) -> None: ...

    def close(self) -> None: ...


@dataclass
class StepContext:
    loaded: LoadedProtocol
    plan: Plan
    bench: Bench
    operator: Operator
    units_dir: Path
    journal: JournalView
    stop_requested: Callable[[], bool]
    processing: ProcessingSettings
    monitor: Publisher = NULL_PUBLISHER  # the live monitor (--monitor), or nothing

    def unit(self, step_id: str) -> h5py.File:
        """Open the completed unit of an earlier step (read-only)."""
        return open_unit(self.units_dir, step_id)

    def trial_step(self, configuration: int) -> TrialStep:
        """The first trial step of a configuration: its settings (device, factors) and joints."""
        return next(
            s for s in self.plan.steps if isinstance(s, TrialStep) and s.configuration == configuration
        )


@dataclass(frozen=True)
class StepOutcome:
    """What a step produced: how to write its unit, a one-line summary, and an optional stop.

    `stop` set means: write the unit (so the record is kept) but stop the session with this error; the
    step is redone on resume."""

    fill: Fill | None
    summary: str
    stop: UserError | None = None
