"""A readable table of a Plan (`run-protocol --plan PROTOCOL`)."""

from __future__ import annotations

from .plan_steps import Plan, TrialStep
from .wording import counted


def format_matrix_table(plan: Plan) -> list[str]:
    """The expanded test matrix: one row per configuration, one column per declared factor."""
    rows: dict[int, TrialStep] = {}
    trials: dict[int, int] = {}
    for step in plan.steps:
        if isinstance(step, TrialStep) and step.brace == "on":
            rows.setdefault(step.configuration, step)
            trials[step.configuration] = trials.get(step.configuration, 0) + 1
    factors: list[str] = []
    for step in rows.values():
        factors += [f for f, _ in step.settings.factors if f not in factors]
    header = ["key", "run", "set", *factors, "trajectory", "trials"]
    body = [
        [
            str(k),
            str(st.run),
            st.set,
            *[st.settings.level(f) or "-" for f in factors],
            f"{st.trajectory.name or st.trajectory.profile} ({_kinds(st)})",
            str(trials[k]),
        ]
        for k, st in rows.items()
    ]
    widths = [max(len(r[i]) for r in [header, *body]) for i in range(len(header))]
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip()]
    out.append("  ".join("-" * w for w in widths))
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in body]
    return out


def _kinds(step: TrialStep) -> str:
    """The trajectory kind(s) a trial commands: its trajectory's, or its joints' (multi-joint)."""
    motions = step.joint_trajectories or (("", step.trajectory),)
    return ", ".join(dict.fromkeys(t.profile for _, t in motions))


def format_plan_table(plan: Plan) -> str:
    width = max(len(s.id) for s in plan.steps)
    lines = [f"Plan of {plan.protocol_name} (sha256 {plan.protocol_sha256[:16]}...)", ""]
    joints = next((s.joints for s in plan.steps if isinstance(s, TrialStep)), ())
    if joints:
        lines += [f"Driven joints ({len(joints)}, in channel order): {', '.join(joints)}", ""]
    lines += ["Test matrix:", *format_matrix_table(plan), "", "Steps:"]
    lines.append(f"{'#':>4}  {'id':<{width}}  {'kind':<18}  {'robot s':>8}  what")
    lines.append(f"{'-' * 4}  {'-' * width}  {'-' * 18}  {'-' * 8}  {'-' * 40}")
    below = " " * (4 + 2 + width + 2 + 18 + 2 + 8 + 2 + 2)  # under the step's "what", indented
    for i, step in enumerate(plan.steps, start=1):
        t = f"{step.robot_time_s:8.1f}" if step.robot_time_s else " " * 8
        first, *more = step.describe().split("\n")
        lines.append(f"{i:>4}  {step.id:<{width}}  {step.kind:<18}  {t}  {first}")
        lines += [below + line for line in more]
    trials = [s for s in plan.steps if isinstance(s, TrialStep)]
    configs = sorted({s.configuration for s in trials})
    lines.append("")
    lines.append(
        f"{counted(len(plan.steps), 'step')}: {counted(len(trials), 'trial')} over "
        f"{counted(len(configs), 'configuration')}; "
        f"about {plan.robot_time_s / 60:.0f} min of robot motion (brace-off scaling iterations add more)."
    )
    return "\n".join(lines)


def robot_time_text(seconds: float) -> str:
    """A plan's robot time as a run and `--validate` announce it: "2.3 h", "12 min" under 90 minutes, or
    "40 s" under 90 seconds (not "1 min" nor "0 min")."""
    if seconds >= 5400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 60:.0f} min" if seconds >= 90 else f"{seconds:.0f} s"
