"""Comparison step: one parameter across configurations (thesis Chapter 5, §5.7.2 energy charts)."""

from __future__ import annotations

import h5py
import numpy as np

from ..archive.h5util import set_attrs
from ..protocol.plan import CompareStep, configuration_name
from .context import StepContext, StepOutcome


def run(step: CompareStep, ctx: StepContext) -> StepOutcome:
    means, stds, counts, max_angles = [], [], [], []
    for key in step.configurations:
        name = configuration_name(key)
        with ctx.unit(f"process:k{key:02d}") as f:
            cfg = f[f"configurations/{name}"]
            e = cfg["energy_loss_j"][:]
            means.append(float(np.mean(e)) if e.size else float("nan"))
            stds.append(float(np.std(e, ddof=1)) if e.size > 1 else float("nan"))
            counts.append(int(e.size))
            max_angles.append(
                max(float(np.max(cfg[f"trials/{n}/processed/angle_deg"][:])) for n in cfg["trials"])
            )

    def fill(f: h5py.File) -> None:
        g = f.require_group("comparisons").create_group(step.name)
        set_attrs(
            g,
            {
                "parameter": step.parameter,
                "section": step.section,
                "title": step.title,
                "configurations": [int(k) for k in step.configurations],
                "energy_mean_j": means,
                "energy_std_j": stds,
                "energy_cycles": counts,
                "max_angle_deg": max_angles,
            },
        )

    text = ", ".join(f"{k}: {m:.2f} J" for k, m in zip(step.configurations, means, strict=True))
    return StepOutcome(fill, text)
