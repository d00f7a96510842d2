"""docs/architecture.md's recipe for a step kind, followed in a test: a kind declared by its plan step class
and one registry entry (nothing else in the program knows it) is planned, described by `--plan`, run by a
dry run, written to the archive and redone by a resume after the step it reads, then removed again."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import h5py
import pytest

from protocol_runner.archive.h5util import group_name
from protocol_runner.archive.paths import configuration_path
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan_steps import Plan, Step, TrialStep
from protocol_runner.protocol.plan_table import format_plan_table
from protocol_runner.session.journal import Journal
from protocol_runner.session.operator import AutoOperator
from protocol_runner.session.resume import derived_from, first_rig_step
from protocol_runner.session.rigs import SimulatedBench
from protocol_runner.session.runner import Runner
from protocol_runner.session.setup import create_session, load_session_protocol
from protocol_runner.steps import registry
from protocol_runner.steps.context import StepContext, StepOutcome

KEY = 1  # elbow_example's first configuration: a short sinusoid


@dataclass(frozen=True)
class NoteStep(Step):
    """The toy kind: a note on a recording, kept in the archive beside it."""

    reads: str  # the trial whose recording the note is about
    note: str

    background: ClassVar[bool] = False  # its function is registered in this process only

    def describe(self) -> str:
        return f"note on {self.reads}: {self.note}"

    def inputs(self) -> tuple[str, ...]:
        return (self.reads,)


def recording(trial: TrialStep) -> str:
    return f"{configuration_path(trial.configuration)}/trials/{trial.trial}/brace_on/time_s"


def run_note(step: NoteStep, ctx: StepContext) -> StepOutcome:
    trial = ctx.plan.step(step.reads)
    assert isinstance(trial, TrialStep)
    with ctx.unit(step.reads) as unit:  # the unit it declares as its input, complete on disk
        samples = unit[recording(trial)].shape[0]

    def fill(f: h5py.File) -> None:
        g = f.require_group("session/notes").create_group(group_name(step.id))
        g.attrs["note"] = step.note
        g.attrs["about"] = step.reads
        g.attrs["samples"] = samples

    return StepOutcome(fill, f"noted {step.note!r} on {step.reads} ({samples} samples)")


@pytest.fixture
def note_kind(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(registry.STEP_KINDS, "note", run_note)


def with_notes(plan: Plan) -> Plan:
    """`plan` with a note after each brace-on trial (where the plan would place a kind of its own)."""
    steps: list[Step] = []
    for step in plan.steps:
        steps.append(step)
        if isinstance(step, TrialStep) and step.brace == "on":
            steps.append(
                NoteStep(id=f"note:{step.id}", kind="note", reads=step.id, note="strap re-tightened")
            )
    return Plan(plan.protocol_name, plan.protocol_sha256, tuple(steps), plan.only)


def test_a_step_kind_declared_by_its_class_and_one_registry_entry_is_planned_run_and_resumed(
    tmp_path: Path, note_kind: None
) -> None:
    loaded = load_protocol(find_protocol("elbow_example.yaml"))
    session = tmp_path / "session"
    info = create_session(session, loaded, mode="dry-run", seed=7, only=(KEY,), realtime=False)
    stored, plan, _ = load_session_protocol(session, info, force=False)
    noted = with_notes(plan)
    notes = [s for s in noted.steps if isinstance(s, NoteStep)]
    assert notes

    # --plan: its own description, never another kind's
    table = format_plan_table(noted)
    for note in notes:
        line = next(line for line in table.splitlines() if f" {note.id} " in line)
        assert line.split()[2] == "note" and line.endswith(f"note on {note.reads}: strap re-tightened")
    assert table.count("HTML report") == 1
    assert noted.to_json()["steps"][noted.steps.index(notes[0])] == {
        "id": notes[0].id,
        "kind": "note",
        "reads": notes[0].reads,
        "note": "strap re-tightened",
    }

    # resume: a redone trial makes its note be redone; a note needs no rig state of its own
    redone = derived_from(noted, {notes[0].reads})
    assert redone[notes[0].id] == notes[0].reads and notes[1].id not in redone
    assert first_rig_step(noted, {s.id for s in noted.steps if s.id != notes[0].id}) is None

    # a dry run: the note runs after its trial and reaches the archive
    runner = Runner(session, info, stored, noted, SimulatedBench(stored, seed=7), AutoOperator(), quiet=True)
    result = runner.run()
    journal = Journal(session / "journal.jsonl")
    assert {n.id for n in notes} <= set(journal.units)
    with h5py.File(result.archive, "r") as f:
        for note in notes:
            g = f[f"session/notes/{group_name(note.id)}"]
            assert g.attrs["note"] == "strap re-tightened" and g.attrs["about"] == note.reads
            trial = noted.step(note.reads)
            assert isinstance(trial, TrialStep)
            assert g.attrs["samples"] == f[recording(trial)].shape[0] > 0  # it read its trial's recording
        assert f.attrs["status"] == "complete"


def test_a_kind_nobody_registered_is_refused_by_name() -> None:
    with pytest.raises(LookupError, match="no step kind 'note' is registered"):
        registry.run_function("note")


def test_a_step_class_without_a_description_cannot_be_made() -> None:
    @dataclass(frozen=True)
    class Silent(Step):
        pass

    with pytest.raises(TypeError, match="describe"):
        Silent(id="silent", kind="silent")  # type: ignore[abstract]
