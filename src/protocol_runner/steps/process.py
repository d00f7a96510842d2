"""Processing step: one configuration's archived trials -> each joint's device torque, energy, element fit.

Per driven joint `analysis.service.analyse_joints` (without the Bouc-Wen fit, the fit step's) with the
elements that joint carries: transition removal (§3.3.1), zero-phase filtering (§3.2), equal-angle
subtraction of the brace-off torque (§3.3, §5.6), cycles and energy per cycle (Eq 10-12), the fit of the
joint's elastic elements (§6.1); the configuration's `total_energy_loss_j` sums the joints' k-th complete
cycles of each trial.
"""

from __future__ import annotations

from collections.abc import Sequence

import h5py
import numpy as np

from ..analysis.pipeline import TrialPair
from ..analysis.service import analyse_joints
from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put
from ..archive.paths import configuration_name, configuration_path, joint_path, recording_path
from ..archive.results import processed_fill, read_recording
from ..protocol.plan_steps import ProcessStep, TrialStep
from ..protocol.processing import element_fit_enabled
from ..protocol.wording import counted
from .context import StepContext, StepOutcome
from .recording import joint_trajectories


def run(step: ProcessStep, ctx: StepContext) -> StepOutcome:
    name = configuration_name(step.configuration)
    cfg_step = ctx.trial_step(step.configuration)
    joints = [j for j, _ in joint_trajectories(cfg_step, ctx)]
    recordings = []
    for joint in joints:
        pairs = []
        for n, (on_id, off_id) in enumerate(step.trials, start=1):
            with ctx.unit(on_id) as f_on, ctx.unit(off_id) as f_off:
                on, off = (
                    read_recording(f[joint_path(recording_path(step.configuration, n, brace), joint)])
                    for f, brace in ((f_on, "on"), (f_off, "off"))
                )
                pairs.append(TrialPair(on, off, trial=n))
        recordings.append((joint, pairs))
    analysis = analyse_joints(recordings, ctx.processing, devices=joint_devices(ctx, cfg_step, joints))
    total = analysis.total_energy_loss_j
    fills = [
        processed_fill(joint_path(name, joint), one, ctx.processing)
        for joint, one in zip(joints, analysis.analyses, strict=True)
    ]
    names = np.array(joints, dtype=h5py.string_dtype())

    def fill(f: h5py.File) -> None:
        for one in fills:
            one(f)
        cfg = f.require_group(configuration_path(step.configuration))
        put(cfg, "total_energy_loss_j", total, "J")
        put(cfg, "total_energy_cycle_trial", analysis.total_energy_cycle_trial, "1")
        cfg.attrs[JOINTS_ATTR] = names

    if len(joints) == 1:
        energy = analysis.analyses[0].processed.energy
        summary = (
            f"{counted(energy.n, 'cycle')}, energy {energy.mean_j:.2f} +- {energy.std_j:.2f} J"
            if energy.n
            else "no complete cycle"
        )
    else:
        parts = [
            f"{j} {a.processed.energy.mean_j:.2f} J"
            for j, a in zip(joints, analysis.analyses, strict=True)
            if a.processed.energy.n
        ]
        mean = f"{float(np.mean(total)):.2f} J" if total.size else "none"
        summary = ", ".join([counted(total.size, "cycle"), *parts, f"total {mean}"])
    return StepOutcome(fill, summary)


def joint_devices(
    ctx: StepContext, cfg_step: TrialStep, joints: Sequence[str]
) -> dict[str, Sequence[object] | None]:
    """Each joint's elements for the element fit and the elements backbone: None when the element fit is off
    or the joint is not fitted (`fitted_joints`)."""
    enabled = element_fit_enabled(ctx.loaded)
    fitted = fitted_joints(cfg_step, joints)
    return {j: cfg_step.settings.device_of(j) if enabled and j in fitted else None for j in joints}


def fitted_joints(cfg_step: TrialStep, joints: Sequence[str]) -> list[str]:
    """The joints whose loops the Bouc-Wen model is fitted to: those carrying device elements (elsewhere a
    joint's loop is the sensors' noise), or every joint when none carries any (the brace's own loop)."""
    carrying = [j for j in joints if any(e.joint == j for e in cfg_step.settings.device)]
    return carrying or list(joints)
