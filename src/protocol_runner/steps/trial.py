"""Trial step: trajectory -> safety envelope -> 100 Hz output while acquiring inputs at 1 kHz.

Brace-on trials command the plan's trajectory. A brace-off trial commands the brace-on trial's measured
output (thesis §3.3.2: only then are torques compared at the same angles) through the inverse of the
servo's first-order lag (§2.4.2, `analysis.scaling.lag_input`, so that the brace-off run follows it in
time, not only in range), rescaled by the Eq 8 iteration (analysis/scaling.py) until its cycles' turning
points match the brace-on cycles' within the protocol's tolerance; every iteration is a robot run and is
recorded (`brace_off/scaling`). Raw codes and converted values are kept.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt

from ..analysis.filters import lowpass
from ..analysis.scaling import ScalingResult, cycle_range, lag_input, scale_brace_off_input
from ..analysis.transition import command_on_input_base, transition_index
from ..archive.attrs import ATTRIBUTES, FACTORS, STATUS, STEP_ID
from ..archive.h5util import SIGNAL, put, put_attrs
from ..archive.paths import configuration_path, recording_path
from ..errors import HardwareUnavailable
from ..hardware.joint import TrialRecording
from ..hardware.motion import run_motion
from ..protocol.plan_steps import TrialStep
from ..protocol.sampling import sample_trajectory
from ..protocol.settings import configuration_attributes
from ..protocol.trajectory_record import Trajectory
from .context import StepContext, StepOutcome
from .recording import put_commands, put_scan

FloatArray = npt.NDArray[np.float64]
COMMAND_SMOOTHING_HZ = 5.0
COMMAND_SMOOTHING_ORDER = 4


def command_deg(trajectory: Trajectory, ctx: StepContext) -> FloatArray:
    """Sample a plan trajectory at the output rate (real joint angles, one per tick)."""
    return sample_trajectory(trajectory, ctx.bench.rig.output_rate_hz, ctx.loaded.base_dir)


@dataclass(frozen=True)
class _BraceOn:
    time_s: FloatArray
    angle_deg: FloatArray
    command_time_s: FloatArray
    command_deg: FloatArray


KEPT_BRACE_ON_MAX = 32
"""Brace-on recordings kept in memory at most (each holds a trial's scan, ~1 MB; a set of four configurations
of three trials has 12 of them before its first brace-off trial). Beyond it the oldest are dropped: their
twins read the unit."""

_kept_brace_on: dict[tuple[str, str], _BraceOn] = {}
"""(units folder, brace-on step id) -> that trial's recording exactly as its unit stores it (`put_scan`,
`put_commands`: the angle at the stored precision), kept by the process that ran it until its brace-off twin
reads it, so the twin does not read the unit back from disk. A twin run by another process (a resume), or
after the memory was dropped, reads the unit."""


def _keep_brace_on(ctx: StepContext, step: TrialStep, rec: TrialRecording) -> None:
    if not any(isinstance(s, TrialStep) and s.twin == step.id for s in ctx.plan.steps):
        return  # no brace-off trial follows this one
    if len(_kept_brace_on) >= KEPT_BRACE_ON_MAX:
        del _kept_brace_on[next(iter(_kept_brace_on))]  # the oldest
    _kept_brace_on[(str(ctx.units_dir), step.id)] = _BraceOn(
        np.asarray(rec.input_time_s),
        np.asarray(rec.angle_deg, dtype=SIGNAL),
        np.asarray(rec.command_time_s),
        np.asarray(rec.command_deg),
    )


def _read_brace_on(ctx: StepContext, step: TrialStep) -> _BraceOn:
    assert step.twin is not None
    kept = _kept_brace_on.pop((str(ctx.units_dir), step.twin), None)
    if kept is not None:
        return kept
    with ctx.unit(step.twin) as f:
        return brace_on_in_unit(f, step)


def brace_on_in_unit(f: h5py.File, step: TrialStep) -> _BraceOn:
    """The recording of the brace-on trial of `step` (a trial of either brace) as its unit `f` stores it."""
    g = f[recording_path(step.configuration, step.trial, "on")]
    return _BraceOn(g["time_s"][:], g["angle_deg"][:], g["command_time_s"][:], g["command_deg"][:])


def run(step: TrialStep, ctx: StepContext) -> StepOutcome:
    rig = ctx.bench.rig
    ctx.bench.fit_brace(step.settings if step.brace == "on" else None)
    ctx.bench.begin_step(step.id)
    scaling: ScalingResult | None = None
    try:
        if step.brace == "on":
            cmd = command_deg(step.trajectory, ctx)
            rec = run_motion(rig, [cmd], where=step.id, stop_requested=ctx.stop_requested)[0]
        else:
            rec, scaling = _run_brace_off(step, ctx)
    except HardwareUnavailable as exc:
        partial = (getattr(exc, "partial_recording", None) or (None,))[0]
        if partial is None:
            raise
        # A board failed mid-trial (e.g. unplugged): keep what was recorded as a failed trial (it is redone
        # on resume), then stop the session; the runner parks the joint if the output board still answers.
        summary = f"failed after {partial.input_time_s.size} samples: {exc.message}"
        return StepOutcome(_fill(step, ctx, partial, None, status="failed"), summary, stop=exc)
    fill = _fill(step, ctx, rec, scaling)
    if step.brace == "on":
        _keep_brace_on(ctx, step, rec)
    lo, hi = float(np.min(rec.angle_deg)), float(np.max(rec.angle_deg))
    summary = (
        f"angle {lo:.0f}..{hi:.0f} deg, torque {np.min(rec.torque_nm):.0f}..{np.max(rec.torque_nm):.0f} N*m"
    )
    if scaling is not None:
        error = scaling.best.range_error_deg
        summary += f", scaling {len(scaling.history)} run(s), cycle range error {error:.2f} deg"
        if not scaling.converged:
            tolerance = ctx.loaded.protocol.processing.brace_off_scaling.tolerance_deg
            summary += f" (NOT within {tolerance:g} deg: kept, flagged in trials.csv)"
    return StepOutcome(fill, summary)


def _run_brace_off(step: TrialStep, ctx: StepContext) -> tuple[TrialRecording, ScalingResult]:
    rig = ctx.bench.rig
    proc = ctx.processing
    on = _read_brace_on(ctx, step)
    # The brace-on output becomes the brace-off input. It is smoothed first (zero-phase, 4th order at
    # COMMAND_SMOOTHING_HZ): the joint's 0.2 s lag passes nothing above ~1 Hz, and the sensor noise and
    # the corners where the brace's stops bite would otherwise break the acceleration envelope.
    nyquist = 0.5 * rig.input_rate_hz
    smooth = lowpass(
        on.angle_deg,
        kind="butterworth",
        order=COMMAND_SMOOTHING_ORDER,
        cutoff=COMMAND_SMOOTHING_HZ / nyquist,
        name=f"{step.twin} angle_deg",
    )
    cmd_in = command_on_input_base(on.command_time_s, on.command_deg, on.time_s)
    start = transition_index(cmd_in, on.angle_deg, proc.transition_tolerance_deg, proc.transition_points)
    # from the transition point on (§3.3.2: "index 0 corresponds to the transition point"); the rig moves
    # from its park angle to the first sample exactly as a brace-on trial does (its own transition)
    t_after = on.time_s[start:] - on.time_s[start]
    # the input whose output is the brace-on output: the servo's first-order lag inverted (§2.4.2). Its
    # last time constant is not sent: that input would only act after the brace-on recording ends, and
    # there the derivative of the smoothed angle carries the filter's edge.
    tau = ctx.loaded.protocol.rig.time_constant_s
    ticks = np.arange(0.0, float(t_after[-1]) - tau, 1.0 / rig.output_rate_hz)
    u = np.interp(ticks, t_after, lag_input(t_after, smooth[start:], tau))
    # the range to match is that of the brace-on cycles (their turning points), not of the approach
    target = cycle_range(smooth[start:], proc.reversal_deg)
    recordings: list[TrialRecording] = []

    def run_once(input_deg: FloatArray) -> FloatArray:
        k = len(recordings)
        rec = run_motion(
            rig, [input_deg], where=f"{step.id} (scaling run {k + 1})", stop_requested=ctx.stop_requested
        )[0]
        recordings.append(rec)
        # smoothed as the target was, so that both turning-point levels are free of the sensor noise
        angle = lowpass(
            np.asarray(rec.angle_deg, dtype=np.float64),
            kind="butterworth",
            order=COMMAND_SMOOTHING_ORDER,
            cutoff=COMMAND_SMOOTHING_HZ / nyquist,
            name=f"{step.id} angle_deg",
        )
        return np.interp(rec.command_time_s, rec.input_time_s, angle)

    scaling_spec = ctx.loaded.protocol.processing.brace_off_scaling
    result = scale_brace_off_input(
        u,
        target,
        run_once,
        tolerance_deg=scaling_spec.tolerance_deg,
        max_iterations=scaling_spec.max_iterations,
        transition_tolerance_deg=proc.transition_tolerance_deg,
        transition_points=proc.transition_points,
        input_limits_deg=rig.joints[0].limits.range_deg,
        reversal_deg=proc.reversal_deg,
    )
    return recordings[result.best.iteration], result


def configuration_group_attributes(step: TrialStep, ctx: StepContext) -> dict[str, Any]:
    """The `/configurations/<name>` attributes (docs/archive.md): identity, trajectory and settings."""
    return {
        "key": step.configuration,
        "run": step.run,
        "set": step.set,
        "condition": next(s.condition for s in ctx.loaded.protocol.sets if s.name == step.set),
        "profile": step.trajectory.profile,
        "trajectory_name": step.trajectory.name or step.trajectory.profile,
        **configuration_attributes(step.settings),
    }


def put_configuration(f: h5py.File, key: int, attrs: dict[str, Any]) -> h5py.Group:
    """The `/configurations/<name>` group with its attributes (`configuration_group_attributes`): the
    layout's own names, and per factor its level and quantities."""
    cfg = f.require_group(configuration_path(key))
    own = ATTRIBUTES["configuration"]
    fixed = {k: v for k, v in attrs.items() if k in own and k != FACTORS}
    put_attrs(cfg, "configuration", fixed, dynamic={k: v for k, v in attrs.items() if k not in own})
    cfg.attrs[FACTORS] = np.array(attrs[FACTORS], dtype=h5py.string_dtype())
    return cfg


def recording_attrs(
    step: TrialStep, status: str, trajectory_json: str, lateness_s: FloatArray, input_time_s: FloatArray
) -> dict[str, Any]:
    """The attributes of a `trials/<n>/brace_<b>` group (docs/archive.md)."""
    return {
        STEP_ID: step.id,
        "brace": step.brace,
        STATUS: status,
        "trajectory": trajectory_json,
        "tick_lateness_p99_s": float(np.percentile(lateness_s, 99)) if lateness_s.size else 0.0,
        "tick_lateness_max_s": float(np.max(lateness_s)) if lateness_s.size else 0.0,
        # output-to-input alignment: when the first input row was taken, relative to the first tick
        "input_start_offset_s": float(input_time_s[0]) if input_time_s.size else 0.0,
    }


def _fill(
    step: TrialStep,
    ctx: StepContext,
    rec: TrialRecording,
    scaling: ScalingResult | None,
    *,
    status: str = "complete",
):
    cfg_attrs = configuration_group_attributes(step, ctx)
    lateness = rec.tick_lateness_s

    def fill(f: h5py.File) -> None:
        put_configuration(f, step.configuration, cfg_attrs)
        g = f.create_group(recording_path(step.configuration, step.trial, step.brace))
        put_scan(g, rec)
        put_commands(g, rec, full=True)
        trajectory = json.dumps(step.trajectory.to_json())
        put_attrs(g, "recording", recording_attrs(step, status, trajectory, lateness, rec.input_time_s))
        if scaling is not None:
            s = g.create_group("scaling")
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

    return fill
