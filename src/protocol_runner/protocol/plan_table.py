"""A readable table of a Plan (`run-protocol --plan PROTOCOL`)."""

from __future__ import annotations

from .plan import (
    CalibrationCheckStep,
    ChecklistStep,
    CompareStep,
    FitStep,
    Plan,
    ProcessStep,
    Step,
    TrialStep,
)


def _describe(step: Step) -> str:
    if isinstance(step, TrialStep):
        st, tr = step.settings, step.trajectory
        if tr.profile == "sinusoid":
            traj = f"{tr.mean_deg:g}+{tr.amplitude_deg:g}*sin(2*pi*t/{tr.period_s:.2f})"
        else:
            traj = f"{tr.profile} {tr.source or ''}".strip()
        extra = f"  (input from {step.twin})" if step.twin else ""
        return (
            f"config {step.configuration:>2} run {step.run:>2} trial {step.trial} brace {step.brace:<3}  "
            f"{st.brace_rom}/{st.robot_rom} fric {st.friction_level} {st.stiffness} {st.speed} {st.preload}  {traj}{extra}"
        )
    if isinstance(step, CalibrationCheckStep):
        return f"set {step.set}: 45 deg step check {step.when}"
    if isinstance(step, ChecklistStep):
        return step.title
    if isinstance(step, ProcessStep):
        return f"config {step.configuration}: transition, filter, equal-angle subtraction, cycles, energy"
    if isinstance(step, FitStep):
        return f"config {step.configuration}: fit {', '.join(step.models)}"
    if isinstance(step, CompareStep):
        return f"{step.title} (§{step.section}): configurations {', '.join(map(str, step.configurations))}"
    return "HTML report"


def format_plan_table(plan: Plan) -> str:
    width = max(len(s.id) for s in plan.steps)
    lines = [f"Plan of {plan.protocol_name} (sha256 {plan.protocol_sha256[:16]}...)", ""]
    lines.append(f"{'#':>4}  {'id':<{width}}  {'kind':<18}  {'robot s':>8}  what")
    lines.append(f"{'-' * 4}  {'-' * width}  {'-' * 18}  {'-' * 8}  {'-' * 40}")
    for i, step in enumerate(plan.steps, start=1):
        t = f"{step.robot_time_s:8.1f}" if step.robot_time_s else " " * 8
        lines.append(f"{i:>4}  {step.id:<{width}}  {step.kind:<18}  {t}  {_describe(step)}")
    trials = [s for s in plan.steps if isinstance(s, TrialStep)]
    configs = sorted({s.configuration for s in trials})
    lines.append("")
    lines.append(
        f"{len(plan.steps)} steps: {len(trials)} trials over {len(configs)} configurations; "
        f"about {plan.robot_time_s / 60:.0f} min of robot motion (brace-off scaling iterations add more)."
    )
    return "\n".join(lines)
