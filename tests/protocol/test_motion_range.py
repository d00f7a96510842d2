"""File-trajectory configurations (24-26, a subject's motion) are the motion file: no robot range or
speed level applies to them, and the plan commands the file's own duration."""

from __future__ import annotations

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import TrialStep
from protocol_runner.protocol.trajectories import load_trajectory_file

from .test_plan import KNEE


def test_file_trajectory_configurations_carry_no_robot_range_and_run_the_whole_file() -> None:
    loaded = load_protocol(KNEE)
    plan = expand(loaded)
    checked = set()
    for step in plan.steps:
        if not isinstance(step, TrialStep) or step.brace != "on":
            continue
        if step.trajectory.profile != "file":
            assert step.settings.level("robot_rom") is not None
            continue
        assert step.settings.level("robot_rom") is None and step.settings.level("speed") is None
        assert step.trajectory.source is not None
        motion = load_trajectory_file(loaded.base_dir / step.trajectory.source)
        assert step.trajectory.duration_s == motion.duration_s
        checked.add(step.configuration)
    assert checked == {24, 25, 26}
