"""Resuming inside a set: the rig's physical state is set up and recorded.

The set's calibration re-check runs with the brace off, as the set's first check did (with the brace still
fitted its springs slow the step response and the re-check failed: exit 4); the operator is asked to take
the brace off for it and to refit it afterwards, with the settings the next trial needs, and each answer
is journaled and archived. The resumed archive holds the same trial data as an uninterrupted run.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from protocol_runner.commands import resume
from protocol_runner.errors import Interrupted
from protocol_runner.hardware.simulator.device import ComposedDevice
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import ChecklistStep
from protocol_runner.session import runner as runner_module
from protocol_runner.session.journal import Journal
from protocol_runner.session.operator import AutoOperator
from protocol_runner.session.rigs import SimulatedBench
from protocol_runner.session.signals import StopFlag
from protocol_runner.steps.operator import Answer

from .conftest import ONLY, assert_same_data, run_dry

SET = "rom_medium_spring"  # configuration 12 (conftest.ONLY): a set with springs fitted


def interrupt_after(monkeypatch: pytest.MonkeyPatch, step_id: str) -> None:
    """The next run stops (as on Ctrl-C) once `step_id` has finished and its unit is handed to the writer:
    at the next safe point (the stop then waits for the unit to be written and journals it)."""
    flag = StopFlag()
    real = runner_module.Runner.record

    def record(self: runner_module.Runner, done_id: str, outcome, **how) -> None:  # type: ignore[no-untyped-def]
        real(self, done_id, outcome, **how)
        if done_id == step_id:
            flag.request("SIGINT")

    monkeypatch.setattr(runner_module.Runner, "record", record)
    monkeypatch.setattr(runner_module, "StopFlag", lambda: flag)


def brace_at_each_step(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, ComposedDevice | None]]:
    """(step id, brace fitted to the simulated joint) at the start of every rig step."""
    seen: list[tuple[str, ComposedDevice | None]] = []
    real = SimulatedBench.begin_step

    def begin_step(self: SimulatedBench, step_id: str) -> None:
        seen.append((step_id, self.sim.device()))
        real(self, step_id)

    monkeypatch.setattr(SimulatedBench, "begin_step", begin_step)
    return seen


def spring_stiffness(device: ComposedDevice | None) -> float:
    """The fitted device's lever-spring stiffness (0 with no device or no lever spring)."""
    springs = [e for e in device.elements if e.type == "lever_spring"] if device is not None else []
    return springs[0].number("stiffness_n_per_mm") if springs else 0.0


def answers(session: Path) -> list[dict[str, object]]:
    events = Journal(session / "journal.jsonl").events
    return [json.loads(e.detail) for e in events if e.kind == "operator_answer"]


def test_resume_inside_a_spring_set_rechecks_brace_off_then_refits(
    tmp_path: Path,
    reference_archive: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    session = tmp_path / "inside"
    with monkeypatch.context() as m:
        interrupt_after(m, "trial:k12:on:1")
        with pytest.raises(Interrupted):
            run_dry(session)
    seen = brace_at_each_step(monkeypatch)
    done = len(Journal(session / "journal.jsonl").units)
    capsys.readouterr()
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0  # was exit 4
    # the plan's steps run and already complete add up to the plan (the report included); the re-check
    # is counted apart
    n_plan = len(expand(load_protocol(find_protocol("knee_phase1.yaml")), only=ONLY).steps)
    assert (
        f"done: {n_plan - done} steps run, {done} already complete, 1 calibration re-check;"
        in capsys.readouterr().out
    )

    steps = dict(seen)
    recheck = f"cal:{SET}:resume-1"
    assert steps[recheck] is None  # the re-check ran brace off, as the set's first check did
    fitted = steps["trial:k12:on:2"]
    assert spring_stiffness(fitted) > 0  # and the brace was refitted after it
    with h5py.File(session / "archive.h5", "r") as f:
        before = f[f"calibration/{SET}/before/joints/knee_flexion"].attrs
        again = f[f"calibration/{SET}/resume_1/joints/knee_flexion"].attrs
        assert again["verdict"] == "pass"
        # same condition, same joint: the time constant agrees far inside the protocol's 0.05 s
        assert abs(float(again["time_constant_s"]) - float(before["time_constant_s"])) < 0.01
        archived = [json.loads(e) for e in f["session/events"].asstr()[:]]

    got = answers(session)
    assert [a["prompt"] for a in got] == ["resume-1:calibration", "resume-1:trial:k12:on:2"]
    assert [a["brace"] for a in got] == ["off", "on"]
    assert got[1]["as_in"] == "check:rom_medium_spring:k12"
    assert all(a["answer"] == "done" and a["automatic"] is True for a in got)
    kinds = [e["kind"] for e in archived]
    assert kinds.count("operator_answer") == 2  # the answers reach the archive's events
    assert kinds.index("operator_answer") < kinds.index("calibration_rerun")
    # Done-when: the resumed session's data equal an uninterrupted run's (same seed), bit for bit
    assert_same_data(reference_archive, session / "archive.h5")


class RecordingOperator(AutoOperator):
    """Answers like --yes, and remembers what it was asked (a person at the rig would see the same)."""

    def __init__(self) -> None:
        self.asked: list[ChecklistStep] = []

    def checklist(self, step: ChecklistStep) -> Answer:
        self.asked.append(step)
        return super().checklist(step)


def test_resume_asks_for_spring_preload_brake_and_rom_of_the_next_step(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On the rig nobody but the operator can fit the brace: the resume must ask for every setting."""
    session = tmp_path / "ask"
    with monkeypatch.context() as m:
        interrupt_after(m, "trial:k12:on:2")
        with pytest.raises(Interrupted):
            run_dry(session)
    operator = RecordingOperator()
    monkeypatch.setattr("protocol_runner.commands._operator", lambda automatic: operator)
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0

    setup = Journal(session / "journal.jsonl")  # the plan's own checklist for configuration 12
    assert "check:rom_medium_spring:k12" in setup.units
    resume_prompts = [s for s in operator.asked if s.id.startswith("resume-")]
    assert [s.brace for s in resume_prompts] == ["off", "on"]
    refit = resume_prompts[1]
    assert refit.settings is not None and refit.configuration == 12
    items = " | ".join(refit.items)
    for needed in ("spring", "preload", "brake", "ROM screws"):
        assert needed in items, f"the resume did not ask for the {needed}: {items}"


def test_quitting_at_a_resume_prompt_stops_resumable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    session = tmp_path / "quit"
    with monkeypatch.context() as m:
        interrupt_after(m, "trial:k12:on:1")
        with pytest.raises(Interrupted):
            run_dry(session)

    class Quits(AutoOperator):
        def checklist(self, step: ChecklistStep) -> Answer:
            raise Interrupted(f"stopped by the operator at {step.id}")

    monkeypatch.setattr("protocol_runner.commands._operator", lambda automatic: Quits())
    done = set(Journal(session / "journal.jsonl").units)
    with pytest.raises(Interrupted) as info:
        resume(session, yes=True, force=False, realtime=False, quiet=True)
    assert "--resume" in info.value.message
    assert set(Journal(session / "journal.jsonl").units) == done  # nothing ran, nothing lost


def test_resume_in_the_second_set_with_the_first_sets_analysis_to_redo(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two sets (--only 12,21). The stop falls inside the second set (largest springs) and the first set's
    processing must be redone too (its unit lost, as after a kill -9 while a worker wrote it): the rig is
    still set up for the second set's next trial, after its re-check with the brace off."""
    only = [12, 21]
    reference = tmp_path / "uninterrupted"
    assert run_dry(reference, only=only) == 0
    session = tmp_path / "resumed"
    with monkeypatch.context() as m:
        interrupt_after(m, "trial:k21:on:1")
        with pytest.raises(Interrupted):
            run_dry(session, only=only)
    (session / "units" / "process__k12.h5").write_bytes(b"")  # damaged: redone on resume
    seen = brace_at_each_step(monkeypatch)
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0

    steps = dict(seen)
    assert steps["cal:rom_large_spring:resume-1"] is None
    fitted = steps["trial:k21:on:2"]
    assert spring_stiffness(fitted) > 0  # before: the brace-off state of set 1
    assert [a["as_in"] for a in answers(session)][-1] == "check:rom_large_spring:k21"
    assert_same_data(reference / "archive.h5", session / "archive.h5")
