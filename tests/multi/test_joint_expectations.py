"""Expectations of a campaign of several joints: `joint: <driven joint>` or `joints: all` says whose data
decide each statement, checked before anything moves (exit 2 naming file, line and field), and the
verdicts decided on each joint's own data with the true reason when a statement cannot be decided."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive.paths import joint_groups
from protocol_runner.cli import main
from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.report.evaluate import evaluate_all
from protocol_runner.report.load import load_report_data

from .conftest import LEG_JOINTS

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
    assert (
        f"leg_y.yaml:{_line_of(text, 'joint: elbow_flexion')}: expectations[0].joint: 'elbow_flexion'" in err
    )


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


def _spec(**fields: object) -> ExpectationSpec:
    return ExpectationSpec.model_validate({"id": "x", "text": "t", "metric": "energy_per_cycle", **fields})


def test_the_leg_verdicts_are_decided_and_recorded_per_joint(leg_archive: Path) -> None:
    with h5py.File(leg_archive, "r") as f:
        expectations = f["expectations"]
        knee = expectations["knee_sit_to_stand_energy"]
        assert list(knee.attrs["joints"]) == ["knee_flexion"] and "verdict" not in knee.attrs
        [(joint, part)] = joint_groups(knee, f.attrs["joint"])
        assert (joint, part.attrs["verdict"]) == ("knee_flexion", "met")
        assert part.attrs["reason"].startswith("joint knee_flexion: configuration 3 minus 1: ")
        evidence = json.loads(part["evidence"][()].decode())
        assert [(e["key"], e["trials"]) for e in evidence] == [(3, 3), (1, 3)]
        ankle = joint_groups(expectations["ankle_sit_to_stand_energy"], f.attrs["joint"])
        assert [(j, g.attrs["verdict"]) for j, g in ankle] == [("ankle_flexion", "met")]
        # every joint decided on its own; configuration 2 (fast gait) was left out of this run (--only 1,3)
        gait = joint_groups(expectations["gait_range_speed_free"], f.attrs["joint"])
        assert [j for j, _ in gait] == list(LEG_JOINTS)
        for joint, part in gait:
            assert part.attrs["verdict"] == "not evaluable"
            assert part.attrs["reason"] == (
                f"joint {joint}: configuration 2 was not run (the session ran only 1, 3) "
                "(the rule needs 2 per configuration)."
            )
        assert part.attrs["family"] == 0 and knee["joints/knee_flexion"].attrs["family"] == 2
    report = (leg_archive.parent / "report.html").read_text(encoding="utf-8")
    for joint in LEG_JOINTS:
        assert f'id="expectation-gait_range_speed_free-{joint}"' in report


def test_a_statement_the_joints_data_contradict_is_not_met(leg_archive: Path) -> None:
    data = load_report_data(leg_archive, workers=1)
    less = _spec(joint="knee_flexion", relation="less", configurations=[3], than=[1])
    greater_hip = _spec(joint="hip_flexion", relation="greater", configurations=[3], than=[1])
    knee, hip = evaluate_all([less, greater_hip], data)
    assert (knee.joint, knee.verdict) == ("knee_flexion", "not met")  # the knee loses MORE in sit-to-stand
    # the bare hip loses next to nothing in either motion: the same statement about the hip is not met
    assert (hip.joint, hip.verdict) == ("hip_flexion", "not met")
    knee_energy = [e.mean for e in knee.evidence]
    assert knee_energy[0] > knee_energy[1] > 10 * abs(hip.evidence[0].mean)


def test_a_statement_without_its_joints_data_says_why(leg_archive: Path) -> None:
    data = load_report_data(leg_archive, workers=1)
    gone = _spec(joint="elbow_flexion", relation="greater", configurations=[3], than=[1])
    unnamed = _spec(relation="greater", configurations=[3], than=[1])
    reasons = [(v.verdict, v.reason) for v in evaluate_all([gone, unnamed], data)]
    assert reasons == [
        (
            "not evaluable",
            "joint elbow_flexion is not in this archive (its joints: hip_flexion, knee_flexion, ankle_flexion).",
        ),
        (
            "not evaluable",
            "this archive holds several joints (hip_flexion, knee_flexion, ankle_flexion) and the expectation "
            "names none: declare `joint: <one of them>` or `joints: all`.",
        ),
    ]
