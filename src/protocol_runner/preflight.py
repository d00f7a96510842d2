"""Preflight: everything a run checks before it creates its session folder, in one function.

`--validate`, `--plan`, a run and a resume all call `preflight`, so "valid" means "the run will start":

1. the protocol loads: YAML limits, schema, cross-field checks, and every referenced file confined to the
   protocol's folder, loaded and checked (protocol/loader.py, protocol/validate.py);
2. `--only` is checked against the matrix and the plan is expanded (protocol/plan.py);
3. every commanded trajectory the plan knows before the run is sampled exactly as the run samples it and
   passed through the rig's own safety envelope (`check_plan_envelope`; hardware/safety.py). Brace-off
   trials follow a measured brace-on output, so they are checked when they run.

A problem is an `InvalidInput` (exit 2) naming file, line and field; nothing has been written yet.
"""

from __future__ import annotations

from collections.abc import Iterable
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, cast

from .errors import InvalidInput
from .protocol.loader import LoadedProtocol, format_problems
from .protocol.only import KeySelection
from .protocol.plan import CalibrationCheckStep, Plan, Trajectory, TrialStep, expand

if TYPE_CHECKING:
    from .protocol.loader import Loc

MAX_COMMAND_SAMPLES = 5_000_000
"""Longest commanded trajectory (samples at the output rate): about 14 h at 100 Hz."""


def preflight(loaded: LoadedProtocol, only: KeySelection | Iterable[int] | None = None) -> Plan:
    """The run's checks before anything is written (module docstring); returns the plan."""
    plan = expand(loaded, only=only)
    problems = check_plan_envelope(loaded, plan)
    if problems:
        raise InvalidInput(format_problems(loaded.shown or str(loaded.path), loaded.lines, problems))
    return plan


def check_plan_envelope(loaded: LoadedProtocol, plan: Plan) -> list[tuple[Loc, str]]:
    """The plan-time safety envelope: each commanded trajectory known before the run (brace-on trials,
    calibration checks), sampled as the run samples it, through `hardware.safety.check_trajectory` with
    the rig's limits, command table and Eq 1 range. Returns (location, message) problems."""
    from .hardware.safety import SafetyViolation, check_trajectory
    from .session.rigs import joint_config

    joint = joint_config(loaded)
    rate = joint.output_rate_hz
    problems: list[tuple[Loc, str]] = []
    seen: set[Trajectory] = set()
    for step in plan.steps:
        if not isinstance(step, (TrialStep, CalibrationCheckStep)) or step.trajectory in seen:
            continue
        if isinstance(step, TrialStep) and step.brace == "off":
            continue
        seen.add(step.trajectory)
        loc = _location(loaded, step)
        n = step.trajectory.duration_s * rate
        if n > MAX_COMMAND_SAMPLES:
            problems.append(
                (
                    loc,
                    f"{step.id} lasts {step.trajectory.duration_s:.0f} s: {n:,.0f} samples at {rate:g} Hz, "
                    f"more than the {MAX_COMMAND_SAMPLES:,} a trajectory may have",
                )
            )
            continue
        try:
            check_trajectory(
                _commanded(loaded, step, rate),
                rate,
                joint.limits,
                where=step.id,
                command_table=joint.command_table,
                volts_range_deg=joint.range_deg,
            )
        except SafetyViolation as exc:
            problems.append((loc, _envelope_message(step, exc, rate)))
    return problems


def _commanded(loaded: LoadedProtocol, step: TrialStep | CalibrationCheckStep, rate: float) -> Any:
    """The samples the run sends for this step (the steps' own sampling functions)."""
    if isinstance(step, CalibrationCheckStep):
        from .steps.calibration_check import _command

        return _command(step, rate)
    from .steps.context import StepContext
    from .steps.trial import command_deg

    rig = SimpleNamespace(joint=SimpleNamespace(output_rate_hz=rate))
    ctx = SimpleNamespace(loaded=loaded, bench=SimpleNamespace(rig=rig))
    return command_deg(step.trajectory, cast(StepContext, ctx))


def _envelope_message(step: TrialStep | CalibrationCheckStep, exc: Any, rate: float) -> str:
    bound = exc.limit_value
    allowed = f"{bound[0]:g} to {bound[1]:g}" if isinstance(bound, tuple) else f"±{bound:g}"
    if isinstance(step, CalibrationCheckStep):
        what = "the calibration step"
    elif step.trajectory.source:
        what = f"{step.trajectory.source} (first used by {step.id})"
    else:
        what = f"the {step.trajectory.profile} of {step.id}"
    return (
        f"{what} as sent at {rate:g} Hz breaks the safety envelope: its {exc.limit} reaches "
        f"{exc.value:.6g} {exc.units} at t = {exc.time_s:.3f} s (allowed {allowed} {exc.units})"
    )


def _location(loaded: LoadedProtocol, step: TrialStep | CalibrationCheckStep) -> Loc:
    p = loaded.protocol
    if isinstance(step, CalibrationCheckStep):
        return ("trajectories", "calibration_step")
    if step.trajectory.profile == "human":
        return ("trajectories", "human", str(dict(step.trajectory.params)["name"]), "file")
    if step.trajectory.profile == "identification":
        return ("trajectories", "identification")
    for i, s in enumerate(p.sets):
        for j, cfg in enumerate(s.configurations):
            if cfg.key == step.configuration:
                return ("sets", i, "configurations", j, "speed")
    return ()
