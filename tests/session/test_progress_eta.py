"""The progress line's ETA: the wall time left is learnt from the steps after the first one, whose time
includes the one-time start-up (compiling the simulator's kernels on a first run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.session import progress as progress_module
from protocol_runner.session.progress import Progress


class Clock:
    def __init__(self) -> None:
        self.now_s = 1000.0

    def __call__(self) -> float:
        return self.now_s


def test_the_wall_eta_ignores_the_first_steps_start_up(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plan = expand(load_protocol(find_protocol("elbow_example.yaml")), only=[1])
    steps = [s for s in plan.steps if s.robot_time_s > 0][:3]
    assert len(steps) == 3
    clock = Clock()
    monkeypatch.setattr(progress_module.time, "monotonic", clock)
    progress = Progress(plan, set(), tmp_path / "session.log", quiet=True)
    total_robot_s = sum(s.robot_time_s for s in plan.steps)

    clock.now_s += 3600.0  # the first step: an hour of compiling, whatever its robot time
    progress.step_finished(steps[0], "ok")

    clock.now_s += 0.5 * steps[1].robot_time_s  # then twice as fast as the robot
    progress.step_finished(steps[1], "ok")
    remaining_robot_s = total_robot_s - steps[0].robot_time_s - steps[1].robot_time_s
    expected = progress_module._fmt_s(0.5 * remaining_robot_s)
    progress.close()
    lines = [
        line for line in (tmp_path / "session.log").read_text(encoding="utf-8").splitlines() if "ETA" in line
    ]
    assert lines[0].endswith(", wall ?)")  # no rate is known after the first step
    assert lines[1].endswith(f"(ETA robot {progress_module._fmt_s(remaining_robot_s)}, wall {expected})")
