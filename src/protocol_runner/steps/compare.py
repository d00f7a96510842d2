"""Comparison step: one parameter across configurations (thesis Chapter 5, §5.7.2 energy charts)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import h5py
import numpy as np

from ..archive.h5util import set_attrs
from ..protocol.plan import CompareStep, configuration_name
from .context import StepContext, StepOutcome


def comparison_values(configs: Sequence[h5py.Group]) -> dict[str, list[Any]]:
    """Energy per cycle (mean, sample std, count) and the largest processed angle of each configuration
    group, in order. Used by the session's step and by `--reprocess`, so both give the same numbers."""
    means, stds, counts, max_angles = [], [], [], []
    for cfg in configs:
        e = cfg["energy_loss_j"][:] if "energy_loss_j" in cfg else np.zeros(0)
        means.append(float(np.mean(e)) if e.size else float("nan"))
        stds.append(float(np.std(e, ddof=1)) if e.size > 1 else float("nan"))
        counts.append(int(e.size))
        angles = [
            cfg[f"trials/{n}/processed/angle_deg"][:]
            for n in cfg.get("trials", {})
            if "processed" in cfg[f"trials/{n}"]
        ]
        max_angles.append(max((float(np.max(a)) for a in angles if a.size), default=float("nan")))
    return {
        "energy_mean_j": means,
        "energy_std_j": stds,
        "energy_cycles": counts,
        "max_angle_deg": max_angles,
    }


def run(step: CompareStep, ctx: StepContext) -> StepOutcome:
    files = [ctx.unit(f"process:k{key:02d}") for key in step.configurations]
    try:
        values = comparison_values(
            [
                f[f"configurations/{configuration_name(k)}"]
                for f, k in zip(files, step.configurations, strict=True)
            ]
        )
    finally:
        for f in files:
            f.close()

    def fill(f: h5py.File) -> None:
        g = f.require_group("comparisons").create_group(step.name)
        set_attrs(
            g,
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
