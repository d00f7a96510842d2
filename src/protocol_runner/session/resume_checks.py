"""Before a resume: the checks that refuse one which would silently redo or rewrite recorded work (a changed
seed or `only`, a damaged journal, unit paths it could not save to, a session.json edited against the
journal) and the answer for a session that is already complete. `resume.py` then prepares the rig."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..archive.units import unit_is_complete, unit_path
from ..errors import InvalidInput
from ..protocol.plan_steps import Plan
from ..protocol.step_ids import calibration_id
from .journal import Journal, inspect_journal
from .setup import SessionInfo

if TYPE_CHECKING:
    from ..protocol.only import KeySelection


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


def not_in_plan(plan: Plan, journal: Journal) -> list[str]:
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
    strangers = not_in_plan(plan, journal)
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
