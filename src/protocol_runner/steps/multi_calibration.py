"""Calibration check of a multi-joint protocol: each driven joint's own step inside its own range, one
joint after the other (the others hold where they rest), judged joint by joint against
`calibration_check` (settle error, time constant; drift and change of the time constant since the set's
"before" check). A failure names the joint; the check stops the session unless the operator accepts it.

Unit: `/calibration/<set>/<when>` with attributes `step_id`, `verdict` (the worst of the joints'),
`message`, `joints`, and one group `joints/<joint>` per joint holding what a single-joint check holds
(docs/archive.md).
"""

from __future__ import annotations

import json

import h5py
import numpy as np

from ..analysis.transition import command_on_input_base
from ..archive.h5util import set_attrs
from ..archive.paths import JOINTS
from ..errors import StoppedByCheck
from ..hardware.motion import run_motion
from ..hardware.rig import TrialRecording
from ..protocol.plan import CalibrationCheckStep, calibration_id
from ..protocol.sampling import sample_trajectory
from .calibration_check import StepResponse, analyse_step
from .context import Fill, StepContext, StepOutcome
from .multi_trial import multi_rig
from .recording import put_commands, put_scan


def run(step: CalibrationCheckStep, ctx: StepContext) -> StepOutcome:
    return run_check(step, ctx, record_as=step.id, when=step.when)


def run_check(step: CalibrationCheckStep, ctx: StepContext, *, record_as: str, when: str) -> StepOutcome:
    rig = multi_rig(ctx)
    p = ctx.loaded.protocol
    limits = p.calibration_check
    ctx.bench.begin_step(record_as)
    before = _before_responses(ctx, step) if when != "before" else {}
    results: list[tuple[str, TrialRecording, StepResponse, list[str], float]] = []
    for joint, traj in step.joint_trajectories:
        single = rig.single(joint)
        cmd = sample_trajectory(traj, rig.output_rate_hz, ctx.loaded.base_dir)
        rec = run_motion(single, cmd, where=f"{record_as}, joint {joint}", stop_requested=ctx.stop_requested)
        rig.note_single(joint, single)
        target = traj.number("from_deg") + traj.number("step_deg")
        window = min(1.0, float(p.calibration_step_of(joint).hold_s) / 2)
        cmd_in = command_on_input_base(rec.command_time_s, rec.command_deg, rec.input_time_s)
        resp = analyse_step(rec.input_time_s, cmd_in, rec.angle_deg, target, window)
        problems: list[str] = []
        if resp.settle_error_deg > limits.max_settle_error_deg:
            problems.append(
                f"settle error {resp.settle_error_deg:.2f} deg > {limits.max_settle_error_deg:g} deg"
            )
        lo, hi = limits.time_constant_s
        if not lo <= resp.time_constant_s <= hi:
            problems.append(f"time constant {resp.time_constant_s:.3f} s outside [{lo:g}, {hi:g}] s")
        first = before.get(joint)
        if first is not None:
            drift = abs(resp.settled_deg - first.settled_deg)
            dtau = abs(resp.time_constant_s - first.time_constant_s)
            if drift > limits.max_drift_deg:
                problems.append(
                    f"settled angle drifted {drift:.2f} deg since the set's first check (> {limits.max_drift_deg:g})"
                )
            if dtau > limits.max_time_constant_change_s:
                problems.append(
                    f"time constant changed {dtau:.3f} s since the set's first check (> {limits.max_time_constant_change_s:g})"
                )
        results.append((joint, rec, resp, problems, traj.number("step_deg")))
    message = "; ".join(f"joint {j}: {', '.join(pr)}" for j, _, _, pr, _ in results if pr)
    verdict, stop = "pass", None
    if message:
        text = f"calibration check {record_as} failed: {message}"
        if ctx.operator.accept_failed_check(text):
            verdict = "accepted"
        else:
            verdict = "fail"
            stop = StoppedByCheck(
                f"{text}. The session stopped before the set's trials went on (exit 4). Check the robot's "
                "calibration of the joint(s) named, then continue with --resume (this check is redone first)."
            )
    ctx.monitor.verdict(record_as, verdict, {"set": step.set, "when": when, "message": message})
    summary = f"{verdict}: " + ", ".join(
        f"{j} error {r.settle_error_deg:.2f} deg tau {r.time_constant_s:.3f} s" for j, _, r, _, _ in results
    )
    return StepOutcome(
        _fill(step.set, when, record_as, results, verdict, message, limits.model_dump()), summary, stop
    )


def _before_responses(ctx: StepContext, step: CalibrationCheckStep) -> dict[str, StepResponse]:
    before_id = calibration_id(step.set, "before")
    if before_id not in ctx.journal.units:
        return {}
    out = {}
    with ctx.unit(before_id) as f:
        for joint in step.joints_names():
            g = f[f"calibration/{step.set}/before/{JOINTS}/{joint}"]
            out[joint] = StepResponse(
                settled_deg=float(g.attrs["settled_deg"]),
                settle_error_deg=float(g.attrs["settle_error_deg"]),
                time_constant_s=float(g.attrs["time_constant_s"]),
            )
    return out


def _fill(
    set_name: str,
    when: str,
    step_id: str,
    results: list[tuple[str, TrialRecording, StepResponse, list[str], float]],
    verdict: str,
    message: str,
    limits: dict[str, object],
) -> Fill:
    def fill(f: h5py.File) -> None:
        g = f.require_group(f"calibration/{set_name}").create_group(when)
        set_attrs(
            g, {"step_id": step_id, "verdict": verdict, "message": message, "limits": json.dumps(limits)}
        )
        g.attrs[JOINTS] = np.array([r[0] for r in results], dtype=h5py.string_dtype())
        for joint, rec, resp, problems, step_deg in results:
            jg = g.create_group(f"{JOINTS}/{joint}")
            put_scan(jg, rec)
            put_commands(jg, rec, full=False)
            set_attrs(
                jg,
                {
                    "joint": joint,
                    "verdict": "fail" if problems else "pass",
                    "step_deg": step_deg,
                    "settled_deg": resp.settled_deg,
                    "settle_error_deg": resp.settle_error_deg,
                    "time_constant_s": resp.time_constant_s,
                    "message": "; ".join(problems),
                },
            )

    return fill
