"""Analysis failures: a processing step that cannot be done on the recorded data stops
the session with one message naming configuration, trial and step and saying what to do; it does not
claim that a plain resume helps, because a resume fails the same way."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.h5util import SIGNAL, put
from protocol_runner.archive.units import UnitRecord, sha256_of, unit_path
from protocol_runner.cli import main
from protocol_runner.session.journal import Journal

from .conftest import ONLY

KEY = ONLY[0]


def flatten_brace_on_trial(session: Path, trial: int) -> None:
    """Make a brace-on recording flat (a dead angle sensor) and journal the unit as good."""
    step_id = f"trial:k{KEY:02d}:on:{trial}"
    path = unit_path(session / "units", step_id)
    with h5py.File(path, "r+") as f:
        g = f[f"configurations/config_{KEY:02d}/trials/{trial}/brace_on/joints/knee_flexion"]
        flat = np.zeros(g["angle_deg"].shape)  # a dead angle sensor: 0 V -> 0 deg, far from the command
        del g["angle_deg"]
        put(g, "angle_deg", flat, "deg", dtype=SIGNAL)
    journal = Journal(session / "journal.jsonl")
    journal.unit_done(UnitRecord(step_id, path.name, sha256_of(path), path.stat().st_size))
    for redo in (f"process:k{KEY:02d}", f"fit:k{KEY:02d}"):
        journal.invalidate(redo, "test: redo the analysis on the flattened recording")


def test_flat_recording_stops_with_a_message_naming_configuration_trial_and_step(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = tmp_path / "session"
    shutil.copytree(reference_archive.parent, session)
    (session / "archive.h5").unlink()
    flatten_brace_on_trial(session, trial=2)
    messages = []
    for _ in range(2):  # the second resume shows that resuming alone fails the same way
        assert main(["--resume", str(session), "--yes"]) == 2
        err = capsys.readouterr().err
        messages.append(err[err.index("run-protocol: ") :])
    err = messages[0]
    assert f"configuration {KEY}, trial 2, step process:k{KEY:02d}: trial 2 brace-on:" in err, err
    assert "resumable" not in err and "Traceback" not in err, err
    assert "fail the same way" in err and "--reprocess" in err and "--force" in err, err
    assert messages[1] == messages[0]
    assert (session / "archive.h5").is_file()  # what was recorded is kept in the archive


def test_brace_off_trial_failure_names_its_trial_and_the_recording_it_follows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A brace-off trial derives its input from the brace-on recording (scaling, transition): when that
    analysis fails, the message names the trial and the brace-on recording to check."""
    from protocol_runner.analysis.validation import AnalysisError
    from protocol_runner.protocol.loader import find_protocol, load_protocol
    from protocol_runner.protocol.plan import expand
    from protocol_runner.protocol.plan_steps import TrialStep
    from protocol_runner.steps import failures, registry
    from protocol_runner.steps.context import StepContext

    loaded = load_protocol(find_protocol("knee_phase1.yaml"))
    plan = expand(loaded, only=[KEY])
    step = plan.step(f"trial:k{KEY:02d}:off:2")
    assert isinstance(step, TrialStep)

    def flat(step: TrialStep, ctx: StepContext) -> None:
        raise AnalysisError("input_deg does not move (range 2e-12 deg)")

    monkeypatch.setitem(registry.STEP_KINDS, "trial", flat)
    ctx = StepContext(loaded, plan, None, None, tmp_path / "s" / "units", None, lambda: False, None)  # type: ignore[arg-type]
    with pytest.raises(failures.AnalysisStepFailed) as info:
        failures.run_step(step, ctx)
    message = info.value.message
    assert message.startswith(
        f"configuration {KEY}, trial 2 (brace off), step trial:k{KEY:02d}:off:2: input_deg does not move"
    ), message
    assert f"brace-on recording trial:k{KEY:02d}:on:2" in message and "resumable" not in message
    assert info.value.exit_code == 2
