"""Comparison step: one parameter across configurations (thesis Chapter 5, §5.7.2 energy charts), per
driven joint (`comparisons/<name>/joints/<joint>`) and, for several joints, of their total at the group's
root."""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np

from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put_attrs
from ..archive.paths import comparison_path, configuration_path, joint_groups, joint_path
from ..archive.results import comparison_values
from ..protocol.plan_steps import CompareStep
from .context import StepContext, StepOutcome


def run(step: CompareStep, ctx: StepContext) -> StepOutcome:
    joints = ctx.loaded.protocol.driven_joints
    files = [ctx.unit(unit) for unit in step.inputs()]
    try:
        cfgs = [f[configuration_path(k)] for f, k in zip(files, step.configurations, strict=True)]
        parts = [dict(joint_groups(cfg, ",".join(joints))) for cfg in cfgs]
        per_joint = {j: comparison_values([p[j] for p in parts]) for j in joints}
        total = comparison_values(cfgs) if len(joints) > 1 else None
    finally:
        for f in files:
            f.close()
    identity: dict[str, Any] = {
        "parameter": step.parameter,
        "section": step.section,
        "title": step.title,
        "configurations": [int(k) for k in step.configurations],
    }

    def fill(f: h5py.File) -> None:
        g = f.create_group(comparison_path(step.name))
        put_attrs(g, "comparison", {**identity, **(total or {})})
        g.attrs[JOINTS_ATTR] = np.array(joints, dtype=h5py.string_dtype())
        for joint, values in per_joint.items():
            put_attrs(f.create_group(joint_path(g.name, joint)), "comparison", {**identity, **values})

    shown = total if total is not None else per_joint[joints[0]]
    text = ", ".join(
        f"{k}: {m:.2f} J" for k, m in zip(step.configurations, shown["energy_mean_j"], strict=True)
    )
    return StepOutcome(fill, text)
