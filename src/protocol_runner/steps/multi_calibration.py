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
from ..archive.attrs import JOINT, STEP_ID
from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put_attrs
from ..archive.paths import calibration_path, joint_path
from ..archive.results import Fill
from ..hardware.joint import TrialRecording
from ..hardware.motion import run_motion
from ..protocol.plan_steps import CalibrationCheckStep
from ..protocol.sampling import sample_trajectory
from ..protocol.step_ids import calibration_id
from .calibration_check import StepResponse, analyse_step, check_verdict, response_problems
from .context import StepContext, StepOutcome
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
        rec = run_motion(
            single, [cmd], where=f"{record_as}, joint {joint}", stop_requested=ctx.stop_requested
        )[0]
        rig.note_single(joint, single)
        target = traj.number("from_deg") + traj.number("step_deg")
        window = min(1.0, float(p.calibration_step_of(joint).hold_s) / 2)
        cmd_in = command_on_input_base(rec.command_time_s, rec.command_deg, rec.input_time_s)
        resp = analyse_step(rec.input_time_s, cmd_in, rec.angle_deg, target, window)
        problems = response_problems(resp, limits, before.get(joint))
        results.append((joint, rec, resp, problems, traj.number("step_deg")))
    message = "; ".join(f"joint {j}: {', '.join(pr)}" for j, _, _, pr, _ in results if pr)
    verdict, stop = check_verdict(ctx, record_as, message, "calibration of the joint(s) named")
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
            out[joint] = StepResponse.read(f[joint_path(calibration_path(step.set, "before"), joint)])
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
        g = f.create_group(calibration_path(set_name, when))
        put_attrs(
            g,
            "calibration",
            {STEP_ID: step_id, "verdict": verdict, "message": message, "limits": json.dumps(limits)},
        )
        g.attrs[JOINTS_ATTR] = np.array([r[0] for r in results], dtype=h5py.string_dtype())
        for joint, rec, resp, problems, step_deg in results:
            jg = f.create_group(joint_path(calibration_path(set_name, when), joint))
            put_scan(jg, rec)
            put_commands(jg, rec, full=False)
            put_attrs(
                jg,
                "calibration_joint",
                {
                    JOINT: joint,
                    "verdict": "fail" if problems else "pass",
                    "step_deg": step_deg,
                    **resp.attrs(),
                    "message": "; ".join(problems),
                },
            )

    return fill
