"""Resuming a session: what the rig must look like before the first step, and the set's calibration re-check.

The software cannot see the rig's physical state (brace, spring, preload, brake, ROM stops), which a person
may have changed after a stop. So before the first step that uses the rig, a resume asks the operator for
the state that step needs, as the plan's last checklist before it set it up. When the session stopped
inside a set, the set's calibration check is run again first, in the state of the set's "before" check.
Every answer is journaled (kind `operator_answer`) and so reaches the archive's `/session/events`.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from ..archive.units import fsync_path, unit_is_complete
from ..protocol.plan_steps import CalibrationCheckStep, ChecklistStep, Plan, Step, TrialStep
from ..protocol.step_ids import calibration_id
from .journal import Journal
from .resume_checks import not_in_plan, started_as
from .setup import SessionInfo, changed_files

if TYPE_CHECKING:
    from ..steps.context import Bench, StepContext, StepOutcome
    from ..steps.operator import Operator
    from .progress import Progress


class Runner(Protocol):
    """What resuming needs of the session runner (`session.runner.Runner`, which imports this module)."""

    dir: Path
    info: SessionInfo
    plan: Plan
    bench: Bench
    operator: Operator
    journal: Journal
    units_dir: Path
    protocol_changed: bool

    def record(self, step_id: str, outcome: StepOutcome) -> None: ...


# the rig's state at the start of a session, before any checklist: nothing fitted to the joint
INITIAL_STATE_ITEMS = ("Brace OFF: not fitted to the robot's joint", "Joint free of straps, foam and clamps")


def state_source(plan: Plan, index: int) -> ChecklistStep | None:
    """The checklist that set up the rig for the step at `index` (None: the session's initial state)."""
    return next((s for s in reversed(plan.steps[:index]) if isinstance(s, ChecklistStep)), None)


def describe_state(source: ChecklistStep | None) -> str:
    if source is None or source.brace != "on" or source.settings is None:
        return "brace OFF"
    return f"brace ON, set up for configuration {source.configuration} ({source.settings.summary()})"


def ask_state(runner: Runner, source: ChecklistStep | None, prompt_id: str, purpose: str) -> None:
    """Ask the operator to set the rig up as `source` did (its own items; the initial state without one),
    record the answer, and (dry run) do it."""
    brace = "off" if source is None else source.brace
    prompt = ChecklistStep(
        id=prompt_id,
        kind="operator_checklist",
        set=source.set if source is not None else "",
        title=f"Resuming: {purpose}. The rig must be: {describe_state(source)}",
        items=INITIAL_STATE_ITEMS if source is None else source.items,
        brace=brace,
        configuration=source.configuration if source is not None else None,
        settings=source.settings if source is not None and brace == "on" else None,
    )
    answer = runner.operator.checklist(prompt)  # "q" raises Interrupted: the session stays resumable
    detail = {
        "prompt": prompt_id,
        "purpose": purpose,
        "state": describe_state(source),
        "brace": prompt.brace,
        "as_in": source.id if source is not None else None,
        "items": list(prompt.items),
        "answer": answer.answer,
        "automatic": answer.automatic,
        "answered_utc": answer.answered_utc,
    }
    runner.journal.event("operator_answer", json.dumps(detail, sort_keys=True))
    runner.bench.fit_brace(prompt.settings)


def set_aside(path: Path) -> Path | None:
    """Move a unit file that no longer matches its journal out of the redone step's way, as
    `<name>.replaced-<n>` beside it (not a unit: no `.h5` ending), so that whatever it holds is kept. None
    when there is no file."""
    if not path.is_file():
        return None
    n = 1
    while os.path.lexists(path.with_name(f"{path.name}.replaced-{n}")):
        n += 1
    kept = path.with_name(f"{path.name}.replaced-{n}")
    os.replace(path, kept)
    fsync_path(path.parent)
    return kept


def first_rig_step(plan: Plan, done: set[str]) -> Step | None:
    """The first step still to run that uses the rig or sets it up (analysis steps need no physical state)."""
    return next((s for s in plan.steps if s.id not in done and s.uses_rig), None)


def derived_from(plan: Plan, redone: set[str]) -> dict[str, str]:
    """Each step whose unit was computed from a step in `redone`, directly or through others (each kind's
    `inputs`), with the redone step it comes from: a redone trial is a new recording, so everything made
    from the old one is made again."""
    origin = dict.fromkeys(redone, "")
    for step in plan.steps:  # in plan order: every step comes after the steps it reads
        if step.id in origin:
            continue
        source = next((origin[i] or i for i in step.inputs() if i in origin), None)
        if source is not None:
            origin[step.id] = source
    return {step_id: source for step_id, source in origin.items() if step_id not in redone}


def prepare_resume(runner: Runner, ctx: StepContext, progress: Progress) -> None:
    """Journal the resume, drop damaged units, park, re-check the set's calibration and set the rig up."""
    j = runner.journal
    if not j.ended_cleanly():
        j.event("interrupted", "the previous run ended without a recorded stop (crash, kill or power cut)")
    had_journal = bool(j.events or j.units or j.failed)
    detail = "protocol text or rig file changed; accepted with --force" if runner.protocol_changed else ""
    j.event("resumed", detail)
    override = functools.partial(j.event, "operator_override")  # what --force let through
    if runner.protocol_changed:
        override("resumed with a changed protocol or rig file (--force)")
    changes = changed_files(runner.dir, runner.info)
    if changes:
        override(f"resumed with changed referenced files (--force): {', '.join(changes)}")
    if not had_journal and any(runner.units_dir.glob("*.h5")):
        override("journal.jsonl was missing or held no record; resumed with --force: every step is redone")
    elif j.damaged_lines:
        override(
            f"journal.jsonl had {j.damaged_lines} damaged line(s), ignored; resumed with --force: the steps they "
            "recorded are redone"
        )
    began = started_as(j)
    if began is not None and began != (runner.info.mode, runner.info.seed):  # only with --force
        override(
            f"resumed with --force as {runner.info.mode}, seed {runner.info.seed}, although the session began "
            f"as {began[0]}, seed {began[1]}"
        )
    strangers = not_in_plan(runner.plan, j)
    if strangers:  # only with --force (resume_preflight refuses them otherwise)
        override(
            f"resumed with --force although the journal records steps the plan does not have: {', '.join(strangers)}"
        )
    redone: set[str] = set()
    for step_id, record in list(j.units.items()):
        if not unit_is_complete(runner.units_dir, record):
            kept = set_aside(runner.units_dir / record.file)
            j.invalidate(step_id, "unit file missing, truncated or corrupt")
            progress.info(
                f"{step_id}: its unit file is missing or damaged; the step will be redone"
                + (f" (the file is kept as {kept.name})" if kept is not None else "")
            )
            redone.add(step_id)
    for step_id, source in derived_from(runner.plan, redone).items():
        if step_id in j.units:  # computed from a recording that is made again: made again from the new one
            j.invalidate(step_id, f"derived from {source}, which is redone")
            progress.info(f"{step_id}: derived from {source}, which is redone; the step will be redone too")
    if runner.bench.mode == "hardware":  # after a crash the joint may be anywhere: bring it to rest first
        runner.bench.rig.park(where="park before resuming")
    plan = runner.plan
    first = first_rig_step(plan, set(j.units))
    if first is None:
        return
    n = sum(1 for e in j.events if e.kind == "resumed")  # this resume's number, for the prompts' ids
    set_name = getattr(first, "set", "")
    before = calibration_id(set_name, "before")
    set_trials_pending = any(
        isinstance(s, TrialStep) and s.set == set_name and s.id not in j.units for s in plan.steps
    )
    if before in j.units and first.id != before and set_trials_pending:
        k = 1 + sum(
            1 for key in list(j.units) + list(j.failed) if key.startswith(calibration_id(set_name, "resume-"))
        )
        check = plan.step(before)
        assert isinstance(check, CalibrationCheckStep)
        record_as = calibration_id(set_name, f"resume-{k}")
        ask_state(
            runner,
            state_source(plan, plan.steps.index(check)),
            f"resume-{n}:calibration",
            f"the set's calibration check is run again ({record_as}) in the state of its first check",
        )
        j.event("calibration_rerun", f"{record_as} before continuing set {set_name} at {first.id}")
        progress.info(f"resuming inside set {set_name}: re-running its calibration check first ({record_as})")
        # the check's module imported when it runs, as the registry does (steps/registry.py)
        from ..steps.calibration_check import run_check

        outcome = run_check(check, ctx, record_as=record_as, when=f"resume_{k}")
        runner.record(record_as, outcome)
        progress.info(f"{record_as}: {outcome.summary}")
    if isinstance(first, ChecklistStep):
        return  # the checklist itself asks for the state
    ask_state(
        runner,
        state_source(plan, plan.steps.index(first)),
        f"resume-{n}:{first.id}",
        f"continuing with {first.id}",
    )
