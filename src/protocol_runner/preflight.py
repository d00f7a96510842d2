"""Preflight: everything a run checks before it creates its session folder (docs/protocol.md "What is
checked"). `--validate`, `--plan`, a run and a resume all load the protocol (protocol/loader.py: limits,
schema, cross-field and file checks, every motion's commanded stream) and expand its plan with `--only`
checked (`protocol.plan.expand`) the same way, so "valid" means "the run will start". A problem is an
`InvalidInput` (exit 2) naming file, line and field; nothing has been written yet.

`preflight_warnings` then names what would run but give the analysis nothing to work on: a processed
trial whose commanded angle holds no complete cycle (the processing's own cycle rule, `analysis/cycles.py`,
applied to the commanded samples). `--validate`, `--plan` and a run print them; they stop nothing.
"""

from __future__ import annotations

from .protocol.loaded import LoadedProtocol
from .protocol.plan_steps import Plan, ProcessStep, TrialStep
from .protocol.trajectory_record import Trajectory


def preflight_warnings(loaded: LoadedProtocol, plan: Plan) -> list[str]:
    """One line per trajectory (and joint) whose commanded angle holds no complete cycle, for the processed
    trials of `plan`: "file:line: field: warning: ..." (module docstring)."""
    from .analysis.cycles import complete_cycles
    from .protocol.only import key_spans
    from .protocol.processing import processing_settings
    from .protocol.sampling import sample_trajectory
    from .protocol.yaml_doc import format_problems

    processed = {s.configuration for s in plan.steps if isinstance(s, ProcessStep)}
    settings = processing_settings(loaded)
    rate_hz = loaded.protocol.rig.output.rate_hz  # one output board: every joint's rate
    empty: dict[tuple[str, str], tuple[Trajectory, list[int]]] = {}
    counted: dict[Trajectory, int] = {}  # by the motion itself: a bound field may differ
    for step in plan.steps:
        if not (isinstance(step, TrialStep) and step.brace == "on" and step.configuration in processed):
            continue
        for joint, trajectory in step.joint_trajectories or (("", step.trajectory),):
            if trajectory not in counted:
                angle = sample_trajectory(trajectory, rate_hz, loaded.base_dir)
                hysteresis, reference = settings.cycle_hysteresis_deg, settings.cycle_reference
                cycles = (
                    complete_cycles(angle, hysteresis_deg=hysteresis, reference=reference)
                    if angle.size >= 3
                    else []
                )
                counted[trajectory] = len(cycles)
            if counted[trajectory] == 0:
                motion = (trajectory.name or trajectory.profile, joint)
                empty.setdefault(motion, (trajectory, []))[1].append(step.configuration)
    problems = []
    for (traj_name, joint), (trajectory, keys) in empty.items():
        field = "periods" if trajectory.profile == "sinusoid" else None
        loc = ("trajectories", traj_name, *(("joints", joint) if joint else ()), *((field,) if field else ()))
        of_joint = f", joint {joint}" if joint else ""
        unique = sorted(set(keys))
        which = f"configuration{'s' if len(unique) > 1 else ''} {key_spans(unique)}"
        periods = dict(trajectory.params).get("periods")
        hint = (
            f"a sinusoid needs at least 3 periods for one (it commands {periods:g})"
            if isinstance(periods, float | int)
            else "lengthen the motion"
        )
        problems.append(
            (
                loc,
                f"warning: trajectory '{traj_name}' commands no complete cycle to analyse ({which}{of_joint}): a "
                "cycle runs from one upward crossing of the mean angle to the next, and the partial first and "
                "last cycles are left out (docs/analysis.md), so the processing will find no cycle, energy or "
                f"loop to fit; {hint}",
            )
        )
    return format_problems(loaded.shown, loaded.lines, problems).splitlines() if problems else []
