"""Resuming a session: what the rig must look like before the first step, and the set's calibration re-check.

The software cannot see the rig's physical state (brace on or off, which spring, preload, brake, ROM stops):
after a stop a person may have changed anything. So before the first step that uses the rig, a resume asks
the operator for the state that step needs, exactly as the plan's last checklist before it set it up (a
checklist as the first step asks for itself). When the session stopped inside a set, the set's calibration
check is run again first, in the condition the plan gives calibration checks (the state at the set's
"before" check: the brace off); the operator is asked to set that up, and afterwards to restore the state
the next step needs. Every answer is journaled (kind `operator_answer`, JSON detail) and so reaches the
archive's `/session/events`. In a dry run or with --yes the answers are given automatically, and recorded.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from ..archive.units import unit_is_complete, unit_path
from ..errors import InvalidInput
from ..protocol.plan import (
    CalibrationCheckStep,
    ChecklistStep,
    CompareStep,
    FitStep,
    Plan,
    ProcessStep,
    Step,
    TrialStep,
    calibration_id,
)
from ..protocol.step_ids import step_id as make_step_id
from .journal import Journal, inspect_journal
from .setup import SessionInfo, changed_files

if TYPE_CHECKING:
    from ..protocol.only import KeySelection
    from ..steps.context import Bench, StepContext, StepOutcome
    from ..steps.operator import Operator
    from .progress import Progress


class Runner(Protocol):
    """What resuming needs of the session runner (`session.runner.Runner`)."""

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


def state_prompt(source: ChecklistStep | None, prompt_id: str, purpose: str) -> ChecklistStep:
    """A checklist asking for the state `source` set up (its own items), for a resume."""
    items = INITIAL_STATE_ITEMS if source is None else source.items
    brace = "off" if source is None else source.brace
    return ChecklistStep(
        id=prompt_id,
        kind="operator_checklist",
        set=source.set if source is not None else "",
        title=f"Resuming: {purpose}. The rig must be: {describe_state(source)}",
        items=items,
        brace=brace,
        configuration=source.configuration if source is not None else None,
        settings=source.settings if source is not None and brace == "on" else None,
    )


def ask_state(runner: Runner, source: ChecklistStep | None, prompt_id: str, purpose: str) -> None:
    """Ask the operator to set the rig up as `source` did, record the answer, and (dry run) do it."""
    prompt = state_prompt(source, prompt_id, purpose)
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


def first_rig_step(plan: Plan, done: set[str]) -> Step | None:
    """The first step still to run that uses the rig or sets it up (analysis steps need no physical state)."""
    rig_kinds = (TrialStep, CalibrationCheckStep, ChecklistStep)
    return next((s for s in plan.steps if s.id not in done and isinstance(s, rig_kinds)), None)


def derived_from(plan: Plan, redone: set[str]) -> dict[str, str]:
    """Each step whose unit was computed from a step in `redone`, directly or through others, with the redone
    step it comes from: a brace-off trial follows its brace-on twin's measured output, the processing reads
    both trials of each pair, the fit reads the processing, a comparison the processings. On the rig a
    redone trial is a new recording, so everything made from the old one is made again."""
    origin = dict.fromkeys(redone, "")
    for step in plan.steps:  # in plan order: every step comes after the steps it reads
        if step.id in origin:
            continue
        source = next((origin[i] or i for i in _inputs(step) if i in origin), None)
        if source is not None:
            origin[step.id] = source
    return {step_id: source for step_id, source in origin.items() if step_id not in redone}


def _inputs(step: Step) -> list[str]:
    """The steps whose units `step` reads (derived_from)."""
    from ..steps.compare import units_read

    if isinstance(step, TrialStep) and step.twin is not None:
        return [step.twin]
    if isinstance(step, ProcessStep):
        return [i for pair in step.trials for i in pair]
    if isinstance(step, FitStep):
        return [make_step_id("process", key=step.configuration)]
    if isinstance(step, CompareStep):
        return units_read(step)
    return []


def prepare_resume(runner: Runner, ctx: StepContext, progress: Progress) -> None:
    """Journal the resume, drop damaged units, park, re-check the set's calibration and set the rig up."""
    j = runner.journal
    if not j.ended_cleanly():
        j.event("interrupted", "the previous run ended without a recorded stop (crash, kill or power cut)")
    had_journal = bool(j.events or j.units or j.failed)
    detail = "protocol text or rig file changed; accepted with --force" if runner.protocol_changed else ""
    j.event("resumed", detail)
    if runner.protocol_changed:
        j.event("operator_override", "resumed with a changed protocol or rig file (--force)")
    changes = changed_files(runner.dir, runner.info)
    if changes:
        j.event("operator_override", f"resumed with changed referenced files (--force): {', '.join(changes)}")
    if not had_journal and any(runner.units_dir.glob("*.h5")):
        j.event(
            "operator_override",
            "journal.jsonl was missing or held no record; resumed with --force: every step is redone",
        )
    elif j.damaged_lines:
        j.event(
            "operator_override",
            f"journal.jsonl had {j.damaged_lines} damaged line(s), ignored; resumed with --force: the steps they "
            "recorded are redone",
        )
    began = started_as(j)
    if began is not None and began != (runner.info.mode, runner.info.seed):  # only with --force
        j.event(
            "operator_override",
            f"resumed with --force as {runner.info.mode}, seed {runner.info.seed}, although the session began "
            f"as {began[0]}, seed {began[1]}",
        )
    strangers = _not_in_plan(runner.plan, j)
    if strangers:  # only with --force (resume_preflight refuses them otherwise)
        j.event(
            "operator_override",
            f"resumed with --force although the journal records steps the plan does not have: {', '.join(strangers)}",
        )
    redone: set[str] = set()
    for step_id, record in list(j.units.items()):
        if not unit_is_complete(runner.units_dir, record):
            j.invalidate(step_id, "unit file missing, truncated or corrupt")
            progress.info(f"{step_id}: its unit file is missing or damaged; the step will be redone")
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
        if ctx.loaded.protocol.multi_joint:
            from ..steps.multi_calibration import run_check
        else:
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


# ------------------------------------------------------------------------------------ before a resume


def check_resume_arguments(info: SessionInfo, *, seed: int | None, only: KeySelection | None) -> None:
    """--seed and --only cannot change a session: refuse values other than the session's own."""
    if seed is not None and seed != info.seed:
        raise InvalidInput(
            f"--seed {seed}: the session was created with seed {info.seed} and --resume keeps it; "
            "drop --seed, or start a new session for another seed"
        )
    if only is not None and not _same_keys(only, info.only):
        had = ",".join(map(str, info.only)) if info.only else "every configuration"
        raise InvalidInput(
            f"--only {only.text()}: the session runs {had} and --resume keeps that; "
            "drop --only, or start a new session for other configurations"
        )


def _same_keys(only: KeySelection, keys: Sequence[int]) -> bool:
    """Whether `only` names exactly `keys` (bounded: a range wider than `keys` cannot)."""
    if not keys or any(hi - lo + 1 > len(keys) for lo, hi in only.ranges):
        return False
    return {k for lo, hi in only.ranges for k in range(lo, hi + 1)} == set(keys)


def _refuse_a_damaged_journal(journal_path: Path, units_dir: Path, n_units: int, *, force: bool) -> None:
    """A journal damaged anywhere but its last line (which a crash or a power cut can tear), or one that
    holds no record while finished units exist, would make a resume redo the steps it no longer records:
    refused, before the journal is read for the resume (reading repairs its torn tail), unless `force`."""
    try:
        damage = inspect_journal(journal_path)
    except OSError as exc:
        raise InvalidInput(f"{journal_path}: cannot be read as this session's journal ({exc})") from None
    if force:
        return
    if damage.damaged:
        lines = ", ".join(map(str, damage.damaged[:5])) + (" ..." if len(damage.damaged) > 5 else "")
        raise InvalidInput(
            f"{journal_path}: line{'s' if len(damage.damaged) > 1 else ''} {lines} {'are' if len(damage.damaged) > 1 else 'is'} "
            "not a journal record: the journal was damaged or edited (a crash can only tear its last "
            "line), and a resume would redo every finished step the damaged lines recorded. Restore "
            "journal.jsonl from a copy, or resume with --force to redo them (recorded in the archive)"
        )
    if damage.records == 0 and n_units:
        raise InvalidInput(
            f"{journal_path}: holds no journal record, but {units_dir} holds {n_units} finished step(s); "
            "a resume would redo every step. Restore journal.jsonl from a copy, or resume with --force to "
            "redo them all (recorded in the archive)"
        )


def _refuse_unusable_unit_paths(units_dir: Path, plan: Plan) -> None:
    """Refuse, before any step runs, a `units` that is not a directory (a file, a dangling symbolic link,
    a link loop) and a unit path of the plan held by something other than a regular file (a directory):
    the resume would otherwise record a step again (a trial on the rig) and then fail to save it."""
    if os.path.lexists(units_dir) and not units_dir.is_dir():
        what = "a symbolic link that leads to no directory" if units_dir.is_symlink() else "not a directory"
        raise InvalidInput(
            f"{units_dir}: is {what}; the session's unit files belong in a directory there. Restore it "
            "(or move it away), then resume"
        )
    if not units_dir.is_dir():
        return
    for step in plan.steps:
        path = unit_path(units_dir, step.id)
        if os.path.lexists(path) and not path.is_file():
            what = "a directory" if path.is_dir() else "not a regular file"
            raise InvalidInput(
                f"{path}: is {what}, where the unit file of step {step.id} belongs; a resume could not save "
                "that step. Move it out of the way, then resume"
            )


def _not_in_plan(plan: Plan, journal: Journal) -> list[str]:
    """The finished steps the journal records that the plan does not have: a plan changed since they ran.
    The calibration checks a resume adds (`cal:<set>:resume-<n>`, `prepare_resume`) are the resume's
    own, not the plan's, and do not count."""
    planned = {s.id for s in plan.steps}
    resumed = [calibration_id(name, "resume-") for name in {s.set for s in plan.steps if hasattr(s, "set")}]
    return sorted(
        step for step in journal.units if step not in planned and not any(step.startswith(r) for r in resumed)
    )


def _archive_says_complete(path: Path) -> bool:
    """Whether `path` is an archive that opens and whose root says the session is complete (one that
    `--report` consolidated from the units of a session without an archive says "incomplete": the resume
    then assembles the session's own, with its verdicts)."""
    import h5py

    from ..archive.attrs import STATUS

    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            status = f.attrs.get(STATUS)
    except Exception:  # truncated, not HDF5, unreadable: not the session's finished archive
        return False
    return (status.decode() if isinstance(status, bytes) else str(status)) == "complete"


def started_as(journal: Journal) -> tuple[str, int] | None:
    """The mode and seed the session's first run journaled (its `started` event), or None."""
    first = next((e for e in journal.events if e.kind == "started"), None)
    match = re.fullmatch(r"(\S+), seed (\d{1,30})", first.detail) if first is not None else None
    return (match.group(1), int(match.group(2))) if match else None


def resume_preflight(
    session_dir: Path, plan: Plan, *, force: bool, info: SessionInfo | None = None
) -> str | None:
    """Refuse a resume that would silently redo or rewrite recorded work. Returns a message when the
    session is already complete - every step done, archive and report written (nothing to do; nothing is
    touched) - else None (a session whose report could not be written, e.g. on a full disk, is resumed:
    its archive is assembled again and the report written)."""
    journal_path = session_dir / "journal.jsonl"
    units_dir = session_dir / "units"
    _refuse_unusable_unit_paths(units_dir, plan)
    n_units = len(list(units_dir.glob("*.h5"))) if units_dir.is_dir() else 0
    if not journal_path.exists():
        if n_units and not force:
            raise InvalidInput(
                f"{journal_path}: missing, but {units_dir} holds {n_units} finished step(s); without the "
                "journal a resume would redo every step. Restore journal.jsonl, or resume with --force to "
                "redo them all (recorded in the archive)"
            )
        return None
    _refuse_a_damaged_journal(journal_path, units_dir, n_units, force=force)
    journal = Journal(journal_path)
    began = started_as(journal)
    if info is not None and began is not None and began != (info.mode, info.seed) and not force:
        raise InvalidInput(
            f"{session_dir / 'session.json'}: {info.mode}, seed {info.seed}, but the session began as "
            f"{began[0]}, seed {began[1]} ({journal_path}): session.json was edited, and a resume with "
            "another seed would not record what the session began to. Restore it, or resume with --force "
            "(recorded)"
        )
    strangers = _not_in_plan(plan, journal)
    if strangers and not force:
        shown = ", ".join(strangers[:4]) + (" ..." if len(strangers) > 4 else "")
        raise InvalidInput(
            f"{journal_path}: records finished steps the session's plan does not have ({shown}): "
            f"{session_dir / 'session.json'} (its `only`) or the session's protocol was edited since they "
            "ran. Restore it, or resume with --force to go on with the plan as it is now (recorded)"
        )
    last = next((e for e in reversed(journal.events) if e.kind in ("finished", "resumed", "started")), None)
    to_run = [s for s in plan.steps if s.kind != "report"]
    complete = all(s.id in journal.units and unit_is_complete(units_dir, journal.units[s.id]) for s in to_run)
    written = (session_dir / "report.html").is_file() and _archive_says_complete(session_dir / "archive.h5")
    if last is not None and last.kind == "finished" and complete and written:
        return (
            f"{session_dir} is complete (finished {last.t_utc}): nothing to resume, nothing rewritten. "
            f"Regenerate its report with: run-protocol --report {session_dir}"
        )
    return None
