"""Expectations of a campaign of several joints: `joint: <driven joint>` or `joints: all` says whose data
decide each statement, checked before anything moves (exit 2 naming file, line and field), and the
verdicts decided on each joint's own data with the true reason when a statement cannot be decided."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main

REPO = Path(__file__).resolve().parents[2]
LEG_TEXT = (REPO / "protocols" / "leg_phase2.yaml").read_text(encoding="utf-8")
KNEE_TEXT = (REPO / "protocols" / "knee_phase1.yaml").read_text(encoding="utf-8")


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    shutil.copytree(REPO / "protocols", tmp_path / "protocols")
    return tmp_path / "protocols"


def _line_of(text: str, needle: str, nth: int = 0) -> int:
    lines = [i for i, line in enumerate(text.splitlines(), start=1) if needle in line]
    return lines[nth]


def _validate(path: Path, text: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    path.write_text(text, encoding="utf-8")
    code = main(["--validate", str(path)])
    return code, capsys.readouterr().err


def test_the_shipped_leg_expectations_name_driven_joints(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--validate", str(REPO / "protocols" / "leg_phase2.yaml")]) == 0
    assert "joint: knee_flexion" in LEG_TEXT and "joints: all" in LEG_TEXT


def test_a_joint_that_is_not_driven_is_refused_at_its_line(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = LEG_TEXT.replace("    joint: ankle_flexion\n", "    joint: ankle_flexon\n")
    code, err = _validate(workdir / "leg_x.yaml", text, capsys)
    assert code == 2
    line = _line_of(text, "joint: ankle_flexon")
    assert (
        f"leg_x.yaml:{line}: expectations[1].joint: 'ankle_flexon' is not one of the driven joints "
        "(hip_flexion, knee_flexion, ankle_flexion); did you mean 'ankle_flexion'?"
    ) in err
    # a joint of the rig that this campaign does not drive is refused the same way
    text = LEG_TEXT.replace("    joint: knee_flexion\n", "    joint: elbow_flexion\n")
    code, err = _validate(workdir / "leg_y.yaml", text, capsys)
    assert code == 2
    assert f"leg_y.yaml:{_line_of(text, 'joint: elbow_flexion')}: expectations[0].joint: 'elbow_flexion'" in err


def test_several_joints_need_joint_or_joints_all(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = LEG_TEXT.replace("    joints: all\n", "")
    code, err = _validate(workdir / "leg_none.yaml", text, capsys)
    assert code == 2
    line = _line_of(text, "- id: gait_range_speed_free")
    assert f"leg_none.yaml:{line}: expectations[2]: this campaign drives 3 joints" in err
    assert "`joint: <one of them>`, or `joints: all`" in err
    both = LEG_TEXT.replace("    joints: all\n", "    joints: all\n    joint: knee_flexion\n")
    code, err = _validate(workdir / "leg_both.yaml", both, capsys)
    assert code == 2 and "give at most one of `joint` (one joint) and `joints: all`" in err
    code, err = _validate(workdir / "leg_some.yaml", LEG_TEXT.replace("joints: all", "joints: some"), capsys)
    assert code == 2 and "expectations[2].joints" in err


def test_a_one_joint_campaign_needs_neither_and_accepts_its_own_joint(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    anchor = "  - id: k2_upper_limit\n"
    assert anchor in KNEE_TEXT
    own = KNEE_TEXT.replace(anchor, anchor + "    joint: knee_flexion\n")
    assert _validate(workdir / "knee_own.yaml", own, capsys)[0] == 0
    other = KNEE_TEXT.replace(anchor, anchor + "    joint: hip_flexion\n")
    code, err = _validate(workdir / "knee_other.yaml", other, capsys)
    assert code == 2
    assert "expectations[" in err and "'hip_flexion' is not one of the driven joints (knee_flexion)" in err
