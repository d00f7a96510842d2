"""Comparison step: one parameter across configurations (thesis Chapter 5, §5.7.2 energy charts)."""

from __future__ import annotations

import h5py

from ..archive.h5util import put_attrs
from ..archive.paths import comparison_path, configuration_path
from ..archive.results import comparison_values
from ..protocol.plan_steps import CompareStep
from .context import StepContext, StepOutcome


def run(step: CompareStep, ctx: StepContext) -> StepOutcome:
    files = [ctx.unit(unit) for unit in step.inputs()]
    try:
        values = comparison_values(
            [f[configuration_path(k)] for f, k in zip(files, step.configurations, strict=True)]
        )
    finally:
        for f in files:
            f.close()

    def fill(f: h5py.File) -> None:
        g = f.create_group(comparison_path(step.name))
        put_attrs(
            g,
            "comparison",
            {
                "parameter": step.parameter,
                "section": step.section,
                "title": step.title,
                "configurations": [int(k) for k in step.configurations],
                **values,
            },
        )

    text = ", ".join(
        f"{k}: {m:.2f} J" for k, m in zip(step.configurations, values["energy_mean_j"], strict=True)
    )
    return StepOutcome(fill, text)
