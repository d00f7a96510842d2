"""On the robot a step lasts a minute: every unit is journaled before the next step that moves the joint
starts, so that a crash or a power cut during that step cannot make a resume record a finished trial
again."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from protocol_runner.session import runner as runner_module

from .conftest import run_dry


def _journaled(session: Path) -> set[str]:
    path = session / "journal.jsonl"
    if not path.exists():
        return set()
    return {
        rec["step_id"]
        for rec in (
            json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()
        )
        if rec.get("record") == "unit"
    }


def test_a_session_journals_every_unit_before_the_next_motion(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "s"
    seen: list[tuple[str, set[str]]] = []
    real_run_step = runner_module.run_step

    def run_step(step, ctx):  # type: ignore[no-untyped-def]
        if step.robot_time_s > 0:
            seen.append((step.id, _journaled(session)))
        return real_run_step(step, ctx)

    monkeypatch.setattr(runner_module, "run_step", run_step)
    assert run_dry(session) == 0
    moved: list[str] = []
    for step_id, journaled in seen:
        assert set(moved) <= journaled, (step_id, sorted(set(moved) - journaled))
        moved.append(step_id)
    assert len(moved) >= 6  # calibration checks and the configuration's trials
