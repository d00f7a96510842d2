"""Calibration check (Appendix A "Calibration"): a 45 deg step before and after every set, of each driven
joint inside its own range, one joint after the other (the others hold where they rest).

The response is compared with a first-order lag (thesis §2.4.2: tau = 0.2 s): the settle error and the
fitted time constant must lie within the protocol's `calibration_check` limits, and the "after" check
must agree with the set's "before" check (drift of the settled angle, change of tau), joint by joint. A
failing check stops the session (exit 4) unless the operator accepts it; the verdict is recorded either
way in `/calibration/<set>/<when>`, each joint's check in its `joints/<joint>`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass

import h5py
import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from ..analysis.transition import command_on_input_base
from ..archive.attrs import JOINT, STEP_ID, STEP_RESPONSE
from ..archive.attrs import JOINTS as JOINTS_ATTR
from ..archive.h5util import put_attrs
from ..archive.paths import calibration_path, joint_groups, joint_path
from ..errors import StoppedByCheck
from ..hardware.joint import TrialRecording
from ..protocol.plan_steps import CalibrationCheckStep
from ..protocol.sampling import sample_trajectory
from ..protocol.schema import CalibrationCheckSpec
from ..protocol.step_ids import calibration_id
from .context import StepContext, StepOutcome
from .recording import drive_joint, joint_trajectories, put_commands, put_scan

FloatArray = npt.NDArray[np.float64]
TAU_BOUNDS_S = (0.02, 2.0)  # the time constants searched
TAU_TOLERANCE_S = 1e-5  # the bounded search's absolute tolerance on tau
MOVE_OVER_NOISE = 10.0
"""A time constant is claimed only for a move at least this many times the held angle's standard deviation:
a smaller one (a jammed joint, a step lost in the sensor noise) fits a "time constant" to noise."""


@dataclass(frozen=True)
class StepResponse:
    settled_deg: float
    settle_error_deg: float
    time_constant_s: float

    @classmethod
    def read(cls, g: h5py.Group) -> StepResponse:
        """The response a calibration group (or one joint's group in it) recorded."""
        return cls(*(float(g.attrs[name]) for name in STEP_RESPONSE))

    def attrs(self) -> dict[str, float]:
        return dict(
            zip(STEP_RESPONSE, (self.settled_deg, self.settle_error_deg, self.time_constant_s), strict=True)
        )


def response_problems(
    resp: StepResponse, limits: CalibrationCheckSpec, first: StepResponse | None
) -> list[str]:
    """What is wrong with a step response against the tolerances, and against the set's first check."""
    problems: list[str] = []
    if resp.settle_error_deg > limits.max_settle_error_deg:
        problems.append(f"settle error {resp.settle_error_deg:.2f} deg > {limits.max_settle_error_deg:g} deg")
    lo, hi = limits.time_constant_s
    if not math.isfinite(resp.time_constant_s):
        problems.append(
            f"no time constant: the joint's move does not stand out of the noise of its held angle "
            f"({MOVE_OVER_NOISE:g} times its standard deviation; is the joint jammed?)"
        )
    elif not lo <= resp.time_constant_s <= hi:
        problems.append(f"time constant {resp.time_constant_s:.3f} s outside [{lo:g}, {hi:g}] s")
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
    return problems


def analyse_step(
    time_s: FloatArray,
    command_deg: FloatArray,
    angle_deg: FloatArray,
    target_deg: float,
    settle_window_s: float,
) -> StepResponse:
    """Settled angle over the last `settle_window_s`, its error, and the time constant that best fits the
    response to the commanded move (least squares over tau in [0.02, 2] s); NaN when the joint's move does
    not stand out of the noise of its held angle (`MOVE_OVER_NOISE`)."""
    settled, start, sse = step_fit(time_s, command_deg, angle_deg, settle_window_s)
    tau = math.nan
    # the held angle's standard deviation: the sensor noise and the servo's dither a move must stand out of
    held_noise_deg = float(np.std(angle_deg[time_s >= time_s[-1] - settle_window_s]))
    if not abs(settled - start) < MOVE_OVER_NOISE * held_noise_deg:
        options = {"xatol": TAU_TOLERANCE_S}
        tau = float(minimize_scalar(sse, bounds=TAU_BOUNDS_S, method="bounded", options=options).x)
    return StepResponse(settled_deg=settled, settle_error_deg=abs(settled - target_deg), time_constant_s=tau)


def first_order_response(command_deg: FloatArray, dt_s: float, tau_s: float, y0_deg: float) -> FloatArray:
    """The first-order lag ``tau dy/dt = c - y`` (thesis §2.4.2) at each sample of `command_deg`, the
    command held over each `dt_s` (its exact discretisation ``y[i+1] = a y[i] + (1 - a) c[i]``,
    ``a = exp(-dt / tau)``), from ``y[0] = y0_deg``."""
    a = math.exp(-dt_s / tau_s)
    y, _ = lfilter([1.0 - a], [1.0, -a], command_deg, zi=[a * y0_deg])
    return np.concatenate(([y0_deg], y[:-1]))


def step_fit(
    time_s: FloatArray, command_deg: FloatArray, angle_deg: FloatArray, settle_window_s: float
) -> tuple[float, float, Callable[[float], float]]:
    """The settled angle (mean over the last `settle_window_s`), the starting angle (mean over the first
    0.2 s) and the squared error of the first-order model with time constant tau, the function
    `analyse_step` minimises."""
    dt = float(np.median(np.diff(time_s)))
    settled = float(np.mean(angle_deg[time_s >= time_s[-1] - settle_window_s]))
    y0 = float(np.mean(angle_deg[: max(1, int(0.2 / dt))]))

    def sse(tau: float) -> float:
        model = first_order_response(command_deg, dt, tau, y0)
        # compare shapes: scale the move to the settled angle so a small calibration offset (judged by
        # the settle error) does not bias tau
        span = float(model[-1]) - y0
        if abs(span) > 1e-9:
            model = y0 + (model - y0) * (settled - y0) / span
        return float(np.sum((angle_deg - model) ** 2))

    return settled, y0, sse


def run_check(step: CalibrationCheckStep, ctx: StepContext, *, record_as: str, when: str) -> StepOutcome:
    """Run each driven joint's step, one joint after the other, and judge them; `record_as` is the id the
    unit is stored under (resume checks differ)."""
    p = ctx.loaded.protocol
    limits = p.calibration_check
    ctx.bench.begin_step(record_as)
    joints = joint_trajectories(step, ctx)
    before = _before_responses(ctx, step, [j for j, _ in joints]) if when != "before" else {}
    rate = ctx.bench.rig.output_rate_hz
    results: list[_Checked] = []
    for joint, traj in joints:
        cmd = sample_trajectory(traj, rate, ctx.loaded.base_dir)
        where = record_as if len(joints) == 1 else f"{record_as}, joint {joint}"
        rec = drive_joint(ctx, joint, cmd, where)
        target = traj.number("from_deg") + traj.number("step_deg")
        settle_window = min(1.0, float(p.calibration_step_of(joint).hold_s) / 2)
        cmd_in = command_on_input_base(rec.command_time_s, rec.command_deg, rec.input_time_s)
        resp = analyse_step(rec.input_time_s, cmd_in, rec.angle_deg, target, settle_window)
        problems = response_problems(resp, limits, before.get(joint))
        results.append(_Checked(joint, rec, resp, problems, traj.number("step_deg")))
    if len(results) == 1:
        message = "; ".join(results[0].problems)
        what = "calibration"
    else:
        message = "; ".join(f"joint {r.joint}: {', '.join(r.problems)}" for r in results if r.problems)
        what = "calibration of the joint(s) named"
    # "pass" without a problem; else the operator accepts the failed check, or the session stops
    verdict, stop = "pass", None
    if message:
        text = f"calibration check {record_as} failed: {message}"
        if ctx.operator.accept_failed_check(text):
            verdict = "accepted"
        else:
            verdict = "fail"
            stop = StoppedByCheck(
                f"{text}. The session stopped before the set's trials went on (exit 4). Check the robot's "
                f"{what}, then continue with --resume (this check is redone first)."
            )
    named = [(r, f"{r.joint} " if len(results) > 1 else "") for r in results]  # several joints: named
    numbers: dict[str, object] = {}
    for r, who in named:
        numbers[f"{who.strip()}.settle_error_deg".lstrip(".")] = round(r.response.settle_error_deg, 3)
        numbers[f"{who.strip()}.time_constant_s".lstrip(".")] = round(r.response.time_constant_s, 4)
    ctx.monitor.verdict(record_as, verdict, {"set": step.set, "when": when, **numbers, "message": message})
    summary = f"{verdict}: " + ", ".join(
        f"{who}settle error {r.response.settle_error_deg:.2f} deg, tau {r.response.time_constant_s:.3f} s"
        for r, who in named
    )

    def fill(f: h5py.File) -> None:
        g = f.create_group(calibration_path(step.set, when))
        put_attrs(
            g,
            "calibration",
            {
                STEP_ID: record_as,
                "verdict": verdict,
                "message": message,
                "limits": json.dumps(limits.model_dump()),
            },
        )
        g.attrs[JOINTS_ATTR] = np.array([r.joint for r in results], dtype=h5py.string_dtype())
        for r in results:
            jg = f.create_group(joint_path(g.name, r.joint))
            put_scan(jg, r.rec)
            put_commands(jg, r.rec, full=False)
            put_attrs(
                jg,
                "calibration_joint",
                {
                    JOINT: r.joint,
                    "verdict": "fail" if r.problems else "pass",
                    "step_deg": r.step_deg,
                    **r.response.attrs(),
                    "message": "; ".join(r.problems),
                },
            )

    return StepOutcome(fill, summary, stop)


def run(step: CalibrationCheckStep, ctx: StepContext) -> StepOutcome:
    return run_check(step, ctx, record_as=step.id, when=step.when)


@dataclass(frozen=True)
class _Checked:
    """One joint's check: its recording, its response and what is wrong with it."""

    joint: str
    rec: TrialRecording
    response: StepResponse
    problems: list[str]
    step_deg: float


def _before_responses(
    ctx: StepContext, step: CalibrationCheckStep, joints: list[str]
) -> dict[str, StepResponse]:
    """Each joint's response in the set's "before" check (none when it has not run)."""
    before_id = calibration_id(step.set, "before")
    if before_id not in ctx.journal.units:
        return {}
    with ctx.unit(before_id) as f:
        parts = joint_groups(f[calibration_path(step.set, "before")], ",".join(joints))
        return {joint: StepResponse.read(g) for joint, g in parts}
