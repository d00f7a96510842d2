"""The plan table (`run-protocol --plan`) of a multi-joint campaign shows what every driven joint does: each
trial's motion per joint and each joint's calibration step, readable for twelve joints as for two."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import TrialStep
from protocol_runner.protocol.plan_table import format_plan_table
from protocol_runner.protocol.trajectory_specs import trajectory_kind

from ..multi.test_multi_protocol import LEG_TEXT

REPO = Path(__file__).resolve().parents[2]
SIT = "  sit_to_stand: {kind: file, file: trajectories/leg_sit_to_stand_synthetic.csv}"
PER_JOINT = (
    "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
    "      hip_flexion: {kind: sinusoid, range_deg: [10, 40], speed_deg_s: 15, periods: 4}\n"
    "      knee_flexion: {kind: sinusoid, range_deg: [20, 90], speed_deg_s: 35, periods: 4}\n"
    "      ankle_flexion: {kind: sinusoid, range_deg: [-10, 10], speed_deg_s: 10, periods: 4}"
)


def _table(path: Path) -> str:
    return format_plan_table(expand(load_protocol(path)))


def _step_lines(table: str, step_id: str) -> list[str]:
    """The step's row and the lines shown below it (indented past the row's columns)."""
    lines = table.splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(rf"\s*\d+  {re.escape(step_id)}\s", line))
    more = []
    for line in lines[start + 1 :]:
        if not line.startswith(" " * 12) or not line.strip():
            break
        more.append(line.strip())
    return [lines[start], *more]


@pytest.fixture()
def per_joint_leg(tmp_path: Path) -> Path:
    """leg_phase2 whose sit-to-stand motion is a sinusoid of its own per joint (same period)."""
    assert SIT in LEG_TEXT
    shutil.copytree(REPO / "protocols" / "trajectories", tmp_path / "trajectories")  # inside its folder
    path = tmp_path / "leg_per_joint.yaml"
    path.write_text(LEG_TEXT.replace(SIT, PER_JOINT), encoding="utf-8")
    return path


def test_each_trial_row_shows_every_joints_motion(per_joint_leg: Path) -> None:
    plan = expand(load_protocol(per_joint_leg))
    table = format_plan_table(plan)
    trial = next(s for s in plan.steps if isinstance(s, TrialStep) and s.configuration == 3)
    motions = {j: trajectory_kind(t.profile).describe(t) for j, t in trial.joint_trajectories}
    assert motions["hip_flexion"].startswith("25+15*sin(") and motions["knee_flexion"].startswith(
        "55+35*sin("
    )
    shown = " ".join(_step_lines(table, trial.id))
    for joint, motion in motions.items():
        assert f"{joint}: {motion}" in shown  # not only the first joint's
    # the matrix names the kind every joint commands
    assert re.search(r"sit_to_stand \(sinusoid\)\s+3$", table, re.MULTILINE)


def test_the_calibration_row_shows_each_joints_own_step(per_joint_leg: Path) -> None:
    table = _table(per_joint_leg)
    cal = _step_lines(table, "cal:leg:before")
    assert "45 deg step check" not in table and "30 deg step check" not in table  # one joint's step for all
    assert cal[1:] == [  # leg_phase2's calibration_step, in channel order (the order they run in)
        "hip_flexion: 30 deg step from 10 deg",
        "knee_flexion: 45 deg step from 20 deg",
        "ankle_flexion: 30 deg step from -20 deg",
    ]


def test_a_shared_file_reads_once_for_every_joint_and_twelve_steps_one_line_each() -> None:
    """suit_phase4: twelve joints from one file; twelve calibration steps, one line per joint."""
    suit = REPO / "protocols" / "suit_phase4.yaml"
    loaded = load_protocol(suit)
    table = _table(suit)
    joints = loaded.protocol.driven_joints
    assert len(joints) == 12
    assert f"Driven joints (12, in channel order): {', '.join(joints)}" in table
    trial = _step_lines(table, "trial:k01:on:1")
    assert trial == [trial[0]] and trial[0].endswith(
        "every joint: file trajectories/suit_walk_reach_synthetic.csv"
    )
    cal = _step_lines(table, "cal:suit:after")
    assert [line.split(":")[0] for line in cal[1:]] == list(joints)
    steps = {j: loaded.protocol.calibration_step_of(j) for j in joints}
    assert cal[1:] == [f"{j}: {s.step_deg:g} deg step from {s.from_deg:g} deg" for j, s in steps.items()]


def test_a_single_joint_plan_reads_as_before() -> None:
    table = _table(REPO / "protocols" / "knee_phase1.yaml")
    assert "Driven joints" not in table and "every joint" not in table
    assert _step_lines(table, "cal:brace_rom:before") == [
        next(line for line in table.splitlines() if "cal:brace_rom:before" in line)
    ]
    assert "45 deg step check before" in table


def test_the_cli_prints_every_joint(per_joint_leg: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--plan", str(per_joint_leg)]) == 0
    out = capsys.readouterr().out
    assert "knee_flexion: 55+35*sin(" in out and "ankle_flexion: 0+10*sin(" in out


def test_counts_of_one_read_in_the_singular(capsys: pytest.CaptureFixture[str]) -> None:
    """`--only 2` plans one configuration, and leg_phase2 has one set: not "1 configurations", "1 sets"."""
    assert main(["--plan", str(REPO / "protocols" / "knee_phase1.yaml"), "--only", "2"]) == 0
    assert "6 trials over 1 configuration;" in capsys.readouterr().out
    assert main(["--validate", str(REPO / "protocols" / "leg_phase2.yaml")]) == 0
    assert "leg_phase2: 1 set, 3 configurations, 18 trials, 32 steps," in capsys.readouterr().out
