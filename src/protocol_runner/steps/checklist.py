"""Operator checklist step: the settings to make by hand (one item per factor: its level, quantities,
setup text; bolt torques; device on/off). Answers and timestamps are recorded (`/session/checklists/<step>`)."""

from __future__ import annotations

import h5py

from ..archive.h5util import group_name, put_attrs
from ..archive.paths import CHECKLISTS
from ..protocol.plan_steps import ChecklistStep
from .context import StepContext, StepOutcome


def run(step: ChecklistStep, ctx: StepContext) -> StepOutcome:
    answer = ctx.operator.checklist(step)
    # In a dry run the simulated operator's hands do what the list says.
    ctx.bench.fit_brace(step.settings if step.brace == "on" else None)

    def fill(f: h5py.File) -> None:
        g = f.require_group(CHECKLISTS).create_group(group_name(step.id))
        put_attrs(
            g,
            "checklist",
            {
                "step_id": step.id,
                "title": step.title,
                "items": list(step.items),
                "brace": step.brace,
                "answer": answer.answer,
                "answered_utc": answer.answered_utc,
                "automatic": answer.automatic,
            },
        )

    how = "automatically" if answer.automatic else "by the operator"
    return StepOutcome(fill, f"{answer.answer} ({how})")
