"""Trial and processing steps of a multi-joint protocol (`joints: [...]`).

Trial: every driven joint's trajectory is sampled at the output rate and sent in ONE paced loop (one
synchronous output update per tick for all joints, one input scan of every joint's angle and torque:
`hardware/rig.py`); each joint's stream is checked against its own envelope before anything moves,
and a stop request brakes and parks every joint. A brace-off trial replays the brace-on trial's commanded
motion (every joint's samples, as sent) without the device: the same multi-joint motion, so the torques
are compared at the same commanded angles (the single-joint Eq 8 rescaling of the measured output,
thesis §3.3.2, is not done per joint: docs/protocol.md "Several joints").

Unit layout (docs/archive.md "Several joints"): `trials/<n>/brace_<b>` holds the shared time base
(`time_s`, `command_time_s`, `tick_lateness_s`) and one group per joint `joints/<joint>` with that joint's
recording (the datasets of a single-joint trial group, its `stream/`, on the same time base).

Processing: each joint's pairs go through the single-joint pipeline (transition removal, filtering,
equal-angle subtraction, cycles, energy per cycle: `analysis.service.analyse_joints`) with that
joint's device, written under `configurations/<name>/joints/<joint>/`; the configuration's
`total_energy_loss_j` is the sum over the joints of the energy of the k-th complete cycle of each trial
(as many cycles as the joint with the fewest).
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import h5py
import numpy as np
import numpy.typing as npt

from ..archive.attrs import JOINT
from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put, put_attrs
from ..archive.paths import (
    TRIALS,
    configuration_name,
    configuration_path,
    joint_path,
    put_dataset,
    recording_path,
)
from ..archive.results import Fill, bouc_wen_fill, processed_fill, read_processed_loops, read_recording
from ..errors import HardwareUnavailable
from ..hardware.joint import TrialRecording
from ..hardware.motion import run_motion
from ..hardware.rig import Rig
from ..protocol.plan_steps import FitStep, ProcessStep, TrialStep
from ..protocol.processing import bouc_wen_settings, element_fit_enabled
from ..protocol.sampling import sample_trajectory
from ..protocol.step_ids import step_id
from .context import StepContext, StepOutcome
from .recording import put_commands, put_scan
from .trial import configuration_group_attributes, put_configuration, recording_attrs

FloatArray = npt.NDArray[np.float64]


def multi_rig(ctx: StepContext) -> Rig:
    return ctx.bench.rig


def run_trial(step: TrialStep, ctx: StepContext) -> StepOutcome:
    rig = multi_rig(ctx)
    ctx.bench.fit_brace(step.settings if step.brace == "on" else None)
    ctx.bench.begin_step(step.id)
    if step.brace == "on":
        rate = rig.output_rate_hz
        commands = [sample_trajectory(t, rate, ctx.loaded.base_dir) for _, t in step.joint_trajectories]
    else:
        commands = _brace_on_commands(step, ctx)
    try:
        recs = run_motion(rig, commands, where=step.id, stop_requested=ctx.stop_requested)
    except HardwareUnavailable as exc:
        partial = getattr(exc, "partial_recording", None)
        if not isinstance(partial, tuple):
            raise
        summary = f"failed after {partial[0].input_time_s.size} samples: {exc.message}"
        return StepOutcome(_trial_fill(step, ctx, partial, status="failed"), summary, stop=exc)
    summary = ", ".join(
        f"{j} {np.min(r.angle_deg):.0f}-{np.max(r.angle_deg):.0f} deg"
        for j, r in zip(step.joints, recs, strict=True)
    )
    return StepOutcome(_trial_fill(step, ctx, recs), summary)


def _brace_on_commands(step: TrialStep, ctx: StepContext) -> list[FloatArray]:
    assert step.twin is not None
    with ctx.unit(step.twin) as f:
        return [
            f[joint_path(recording_path(step.configuration, step.trial, "on"), j)]["command_deg"][:]
            for j in step.joints
        ]


def _trial_fill(
    step: TrialStep, ctx: StepContext, recs: tuple[TrialRecording, ...], *, status: str = "complete"
) -> Fill:
    cfg_attrs = configuration_group_attributes(step, ctx)
    shared = recs[0]
    lateness = shared.tick_lateness_s

    def fill(f: h5py.File) -> None:
        cfg = put_configuration(f, step.configuration, cfg_attrs)
        cfg.attrs[JOINTS_ATTR] = np.array(step.joints, dtype=h5py.string_dtype())
        g = f.create_group(recording_path(step.configuration, step.trial, step.brace))
        put_dataset(g, "recording", "time_s", shared.input_time_s)
        put_dataset(g, "recording", "command_time_s", shared.command_time_s)
        put_dataset(g, "recording", "tick_lateness_s", lateness)
        trajectory = json.dumps({j: t.to_json() for j, t in step.joint_trajectories})
        put_attrs(g, "recording", recording_attrs(step, status, trajectory, lateness, shared.input_time_s))
        g.attrs[JOINTS_ATTR] = np.array(step.joints, dtype=h5py.string_dtype())
        for (joint, traj), rec in zip(step.joint_trajectories, recs, strict=True):
            jg = f.create_group(joint_path(g.name, joint))
            put_scan(jg, rec)
            put_commands(jg, rec, full=True)
            put_attrs(jg, "recording_joint", {JOINT: joint, "trajectory": json.dumps(traj.to_json())})

    return fill


def run_process(step: ProcessStep, ctx: StepContext) -> StepOutcome:
    """Each joint's trials through `analysis.service.analyse_joints` (with that joint's device), written
    under `joints/<joint>/`, and the leg's total energy per cycle."""
    from ..analysis.pipeline import TrialPair  # the processing: loaded where it runs (an analysis worker)
    from ..analysis.service import analyse_joints

    name = configuration_name(step.configuration)
    cfg_step = ctx.trial_step(step.configuration)
    joints = cfg_step.joints
    recordings = []
    for joint in joints:
        pairs = []
        for n, (on_id, off_id) in enumerate(step.trials, start=1):
            with ctx.unit(on_id) as f_on, ctx.unit(off_id) as f_off:
                pairs.append(
                    TrialPair(
                        read_recording(f_on[joint_path(recording_path(step.configuration, n, "on"), joint)]),
                        read_recording(
                            f_off[joint_path(recording_path(step.configuration, n, "off"), joint)]
                        ),
                        trial=n,
                    )
                )
        recordings.append((joint, pairs))
    analysis = analyse_joints(recordings, ctx.processing, devices=_devices(ctx, cfg_step))
    total = analysis.total_energy_loss_j
    fills = [
        processed_fill(joint_path(name, joint), one, ctx.processing)
        for joint, one in zip(joints, analysis.analyses, strict=True)
    ]

    def fill(f: h5py.File) -> None:
        for one in fills:
            one(f)
        cfg = f.require_group(configuration_path(step.configuration))
        put(cfg, "total_energy_loss_j", total, "J")
        put(cfg, "total_energy_cycle_trial", analysis.total_energy_cycle_trial, "1")
        cfg.attrs[JOINTS_ATTR] = np.array(joints, dtype=h5py.string_dtype())

    parts = [
        f"{j} {a.processed.energy.mean_j:.2f} J"
        for j, a in zip(joints, analysis.analyses, strict=True)
        if a.processed.energy.n
    ]
    summary = f"{total.size} leg cycles, total {float(np.mean(total)) if total.size else 0.0:.2f} J ({', '.join(parts)})"
    return StepOutcome(fill, summary)


def _devices(ctx: StepContext, cfg_step: TrialStep) -> dict[str, Sequence[object] | None]:
    """Each joint's elements for the element fit and the elements backbone (None when it carries none or
    the element fit is off)."""
    enabled = element_fit_enabled(ctx.loaded)
    return {j: (cfg_step.settings.device_of(j) or None) if enabled else None for j in cfg_step.joints}


def run_fit(step: FitStep, ctx: StepContext) -> StepOutcome:
    """The Bouc-Wen fit per joint (`analysis.service.fit_stored_loops` on that joint's stored processed
    loops) for every driven joint that carries device elements; written under `joints/<joint>/fits/bouc_wen`,
with the joint's model comparison (`fits/element_model`, `fits/models`) when the element fit is on."""
    from ..analysis.model_comparison import compare_stored  # loaded where it runs (an analysis worker)
    from ..analysis.service import fit_stored_loops  # the fit: loaded where it runs (an analysis worker)
    from ..archive.model_results import comparison_fill, read_processed_trials

    if "bouc_wen" not in step.models:
        return StepOutcome(None, "no Bouc-Wen fit asked")
    cfg_step = ctx.trial_step(step.configuration)
    name = configuration_name(step.configuration)
    fitted = [j for j in cfg_step.joints if cfg_step.settings.device_of(j)]  # elsewhere: the sensors' noise
    with ctx.unit(step_id("process", key=step.configuration)) as f:
        cfg = f[configuration_path(step.configuration)]
        loops = {j: read_processed_loops(f[f"{joint_path(cfg.name, j)}/{TRIALS}"]) for j in fitted}
        devices = _devices(ctx, cfg_step)
        trials = {  # the model comparison's input, where the element fit is on
            j: read_processed_trials(f[f"{joint_path(cfg.name, j)}/{TRIALS}"])
            for j in fitted
            if devices[j] is not None
        }
    settings = bouc_wen_settings(ctx.loaded)
    fills: list[Fill] = []
    parts: list[str] = []
    for joint, raw in loops.items():
        bouc_wen = fit_stored_loops(raw, settings, devices[joint])
        fill_one = bouc_wen_fill(joint_path(name, joint), bouc_wen)
        device = devices[joint]
        if device is not None:  # the model comparison of the joint: element model, reduced Dahl, Bouc-Wen
            comparison = compare_stored(trials[joint], device, bouc_wen)
            fill_one = comparison_fill(joint_path(name, joint), fill_one, comparison)
        fills.append(fill_one)
        parts.append(f"{joint} RMSE {bouc_wen.fit.rmse_nm:.2f} N*m, R2 {bouc_wen.fit.r2:.3f}")

    def fill(f: h5py.File) -> None:
        for one in fills:
            one(f)

    return StepOutcome(fill, "; ".join(parts) or "no joint carries a device")
