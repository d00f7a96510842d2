"""Trial step: every driven joint's trajectory -> its safety envelope -> one 100 Hz output update of every
joint per tick while acquiring every joint's inputs at 1 kHz (one scan).

Brace-on trials command the plan's trajectories. A brace-off trial commands each joint's brace-on
measured output (thesis §3.3.2: only then are torques compared at the same angles) through the inverse of
that joint's servo lag (§2.4.2, `analysis.scaling.lag_input`), rescaled by the Eq 8 iteration
(`analysis.scaling.scale_brace_off_inputs`) until each joint's cycle turning points match its brace-on
cycles' within the protocol's tolerance; every iteration is one robot run and is recorded
(`joints/<joint>/scaling`). Unit layout: docs/archive.md.
"""

from __future__ import annotations

import json
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt

from ..analysis.filters import lowpass
from ..analysis.scaling import ScalingResult, cycle_range, lag_input, scale_brace_off_inputs
from ..analysis.transition import command_on_input_base, transition_index
from ..archive.attrs import ATTRIBUTES, FACTORS, JOINT, STATUS, STEP_ID
from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put, put_attrs
from ..archive.paths import configuration_path, joint_groups, joint_path, put_dataset, recording_path
from ..archive.results import Fill
from ..errors import HardwareUnavailable
from ..hardware.joint import TrialRecording
from ..protocol.plan_steps import TrialStep
from ..protocol.sampling import sample_trajectory
from ..protocol.settings import configuration_attributes
from ..protocol.wording import counted
from .context import StepContext, StepOutcome
from .recording import drive, joint_trajectories, put_commands, put_scan

FloatArray = npt.NDArray[np.float64]
COMMAND_SMOOTHING_HZ = 5.0
COMMAND_SMOOTHING_ORDER = 4


def _read_brace_on(
    ctx: StepContext, step: TrialStep
) -> tuple[FloatArray, FloatArray, list[FloatArray], list[FloatArray]]:
    """The brace-on twin's recording of the brace-off trial `step`, as its unit stores it: the shared time
    bases (input, command) and each joint's angle and command, in channel order."""
    assert step.twin is not None
    joints = [j for j, _ in joint_trajectories(step, ctx)]
    with ctx.unit(step.twin) as f:
        g = f[recording_path(step.configuration, step.trial, "on")]
        parts = dict(joint_groups(g, ",".join(joints)))
        return (
            g["time_s"][:],
            g["command_time_s"][:],
            [parts[j]["angle_deg"][:] for j in joints],
            [parts[j]["command_deg"][:] for j in joints],
        )


def run(step: TrialStep, ctx: StepContext) -> StepOutcome:
    ctx.bench.fit_brace(step.settings if step.brace == "on" else None)
    ctx.bench.begin_step(step.id)
    joints = joint_trajectories(step, ctx)
    names = [j for j, _ in joints]
    scaling: tuple[ScalingResult, ...] | None = None
    try:
        if step.brace == "on":
            rate = ctx.bench.rig.output_rate_hz
            commands = [sample_trajectory(t, rate, ctx.loaded.base_dir) for _, t in joints]
            recs = drive(ctx, commands, step.id)
        else:
            recs, scaling = _run_brace_off(step, ctx, names)
    except HardwareUnavailable as exc:
        partial = getattr(exc, "partial_recording", None)  # one recording per joint, as far as it got
        if not partial:
            raise
        # A board failed mid-trial (e.g. unplugged): keep what was recorded as a failed trial (it is redone
        # on resume), then stop the session; the runner parks the joints if the output board still answers.
        summary = f"failed after {partial[0].input_time_s.size} samples: {exc.message}"
        return StepOutcome(_fill(step, ctx, partial, None, status="failed"), summary, stop=exc)
    fill = _fill(step, ctx, recs, scaling)
    who = [f"{j} " if len(names) > 1 else "" for j in names]
    summary = ", ".join(
        f"{w}angle {np.min(r.angle_deg):.0f}..{np.max(r.angle_deg):.0f} deg, "
        f"torque {np.min(r.torque_nm):.0f}..{np.max(r.torque_nm):.0f} N*m"
        for w, r in zip(who, recs, strict=True)
    )
    if scaling is not None:
        errors = ", ".join(f"{w}{s.best.range_error_deg:.2f} deg" for w, s in zip(who, scaling, strict=True))
        summary += f", scaling {counted(len(scaling[0].history), 'run')}, cycle range error {errors}"
        if not all(s.converged for s in scaling):
            tolerance = ctx.loaded.protocol.processing.brace_off_scaling.tolerance_deg
            summary += f" (NOT within {tolerance:g} deg: kept, flagged in trials.csv)"
    return StepOutcome(fill, summary)


def _smoothed(angle_deg: npt.ArrayLike, input_rate_hz: float, name: str) -> FloatArray:
    """An angle low-passed as a brace-off command is made of it (zero-phase, COMMAND_SMOOTHING_ORDER at
    COMMAND_SMOOTHING_HZ)."""
    return lowpass(
        angle_deg,
        kind="butterworth",
        order=COMMAND_SMOOTHING_ORDER,
        cutoff=COMMAND_SMOOTHING_HZ / (0.5 * input_rate_hz),
        name=name,
    )


def _run_brace_off(
    step: TrialStep, ctx: StepContext, joints: list[str]
) -> tuple[tuple[TrialRecording, ...], tuple[ScalingResult, ...]]:
    configs = ctx.bench.rig.joints  # in channel order
    proc = ctx.processing
    time_s, command_time_s, angles_deg, commands_deg = _read_brace_on(ctx, step)
    input_rate = configs[0].input_rate_hz
    label = [f" {j}" if len(joints) > 1 else "" for j in joints]
    # Each joint's brace-on output becomes its brace-off input. It is smoothed first (zero-phase, 4th order
    # at COMMAND_SMOOTHING_HZ): the joint's 0.2 s lag passes nothing above ~1 Hz, and the sensor noise and
    # the corners where the brace's stops bite would otherwise break the acceleration envelope.
    smooth = [
        _smoothed(a, input_rate, f"{step.twin}{w} angle_deg") for a, w in zip(angles_deg, label, strict=True)
    ]
    # from the transition point on (§3.3.2: "index 0 corresponds to the transition point"), the latest of
    # the joints' so that they stay together in time; the rig moves from its park angles to the first
    # samples exactly as a brace-on trial does (its own transition)
    start = max(
        transition_index(
            command_on_input_base(command_time_s, c, time_s),
            a,
            proc.transition_tolerance_deg,
            proc.transition_points,
        )
        for c, a in zip(commands_deg, angles_deg, strict=True)
    )
    t_after = time_s[start:] - time_s[start]
    # the input whose output is the brace-on output: each servo's first-order lag inverted (§2.4.2). Its
    # last time constant is not sent: that input would only act after the brace-on recording ends, and
    # there the derivative of the smoothed angle carries the filter's edge.
    taus = [ctx.loaded.protocol.rig_of(j).time_constant_s for j in joints]
    ticks = np.arange(0.0, float(t_after[-1]) - max(taus), 1.0 / configs[0].output_rate_hz)
    inputs = [
        np.interp(ticks, t_after, lag_input(t_after, s[start:], tau))
        for s, tau in zip(smooth, taus, strict=True)
    ]
    # the range to match is that of the brace-on cycles (their turning points), not of the approach
    targets = [cycle_range(s[start:], proc.reversal_deg) for s in smooth]
    runs: list[tuple[TrialRecording, ...]] = []

    def run_once(inputs_deg: list[FloatArray]) -> list[FloatArray]:
        recs = drive(ctx, inputs_deg, f"{step.id} (scaling run {len(runs) + 1})")
        runs.append(recs)
        # smoothed as the target was, so that both turning-point levels are free of the sensor noise
        return [
            np.interp(
                r.command_time_s,
                r.input_time_s,
                _smoothed(np.asarray(r.angle_deg, dtype=np.float64), input_rate, f"{step.id}{w} angle_deg"),
            )
            for r, w in zip(recs, label, strict=True)
        ]

    scaling_spec = ctx.loaded.protocol.processing.brace_off_scaling
    results = scale_brace_off_inputs(
        inputs,
        targets,
        run_once,
        tolerance_deg=scaling_spec.tolerance_deg,
        max_iterations=scaling_spec.max_iterations,
        transition_tolerance_deg=proc.transition_tolerance_deg,
        transition_points=proc.transition_points,
        input_limits_deg=[c.limits.range_deg for c in configs],
        reversal_deg=proc.reversal_deg,
    )
    return runs[results[0].kept], results


def _fill(
    step: TrialStep,
    ctx: StepContext,
    recs: tuple[TrialRecording, ...],
    scaling: tuple[ScalingResult, ...] | None,
    *,
    status: str = "complete",
) -> Fill:
    """The trial's unit (docs/archive.md): its `/configurations/<name>` attributes (identity, trajectory and
    settings: the layout's own names, and per factor its level and quantities) and its recording."""
    attrs: dict[str, Any] = {
        "key": step.configuration,
        "run": step.run,
        "set": step.set,
        "condition": next(s.condition for s in ctx.loaded.protocol.sets if s.name == step.set),
        "profile": step.trajectory.profile,
        "trajectory_name": step.trajectory.name or step.trajectory.profile,
        **configuration_attributes(step.settings),
    }
    own = ATTRIBUTES["configuration"]
    joints = joint_trajectories(step, ctx)
    names = np.array([j for j, _ in joints], dtype=h5py.string_dtype())
    shared = recs[0]
    lateness = shared.tick_lateness_s
    trajectory = json.dumps(
        step.trajectory.to_json() if not step.joint_trajectories else {j: t.to_json() for j, t in joints}
    )
    recording = {
        STEP_ID: step.id,
        "brace": step.brace,
        STATUS: status,
        "trajectory": trajectory,
        "tick_lateness_p99_s": float(np.percentile(lateness, 99)) if lateness.size else 0.0,
        "tick_lateness_max_s": float(np.max(lateness)) if lateness.size else 0.0,
        # output-to-input alignment: when the first input row was taken, relative to the first tick
        "input_start_offset_s": float(shared.input_time_s[0]) if shared.input_time_s.size else 0.0,
    }

    def fill(f: h5py.File) -> None:
        cfg = f.require_group(configuration_path(step.configuration))
        fixed = {k: v for k, v in attrs.items() if k in own and k != FACTORS}
        put_attrs(cfg, "configuration", fixed, dynamic={k: v for k, v in attrs.items() if k not in own})
        cfg.attrs[FACTORS] = np.array(attrs[FACTORS], dtype=h5py.string_dtype())
        cfg.attrs[JOINTS_ATTR] = names
        g = f.create_group(recording_path(step.configuration, step.trial, step.brace))
        put_dataset(g, "recording", "time_s", shared.input_time_s)
        put_dataset(g, "recording", "command_time_s", shared.command_time_s)
        put_dataset(g, "recording", "tick_lateness_s", lateness)
        put_attrs(g, "recording", recording)
        g.attrs[JOINTS_ATTR] = names
        for k, ((joint, traj), rec) in enumerate(zip(joints, recs, strict=True)):
            jg = f.create_group(joint_path(g.name, joint))
            put_scan(jg, rec)
            put_commands(jg, rec, full=True)
            put_attrs(jg, "recording_joint", {JOINT: joint, "trajectory": json.dumps(traj.to_json())})
            if scaling is not None:
                put_scaling(jg.create_group("scaling"), scaling[k])

    return fill


def put_scaling(s: h5py.Group, scaling: ScalingResult) -> None:
    """A joint's `scaling/` group: the Eq 8 iterations of its brace-off input (docs/archive.md)."""
    h = scaling.history
    put(s, "iteration", [it.iteration + 1 for it in h], "1")
    put(s, "scale", [it.scale for it in h], "1")
    put(s, "input_range_deg", [list(it.input_range_deg) for it in h], "deg")
    put(s, "output_range_deg", [list(it.output_range_deg) for it in h], "deg")
    put(s, "range_error_deg", [it.range_error_deg for it in h], "deg")
    put_attrs(
        s,
        "scaling",
        {
            "converged": bool(scaling.converged),
            "target_range_deg": list(scaling.target_range_deg),
            "kept_iteration": scaling.best.iteration + 1,
        },
    )
