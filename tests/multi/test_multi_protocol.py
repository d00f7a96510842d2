"""Multi-joint protocols: `joints:`, per-joint trajectories and devices, the plan contract, and
the bad inputs refused before anything moves (exit 2 naming file, line, column and joint)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import TrialStep

REPO = Path(__file__).resolve().parents[2]
LEG = REPO / "protocols" / "leg_phase2.yaml"
LEG_TEXT = LEG.read_text(encoding="utf-8")
GAIT = "trajectories/leg_gait_slow_synthetic.csv"


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    shutil.copytree(REPO / "protocols", tmp_path / "protocols")
    return tmp_path / "protocols"


def _refused(path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["--validate", str(path)]) == 2
    return capsys.readouterr().err


def test_leg_protocol_plan_names_joints_in_channel_order_and_a_trajectory_per_joint() -> None:
    loaded = load_protocol(LEG)
    p = loaded.protocol
    assert p.multi_joint and p.driven_joints == ("hip_flexion", "knee_flexion", "ankle_flexion")
    assert [r.output.channel for r in p.rigs] == [5, 8, 10]  # joints 6, 9, 11 (thesis Table 1)
    plan = expand(loaded)
    trial = plan.to_json()["steps"][2]
    assert trial["id"] == "trial:k01:on:1"
    assert trial["joints"] == ["hip_flexion", "knee_flexion", "ankle_flexion"]
    assert set(trial["trajectory"]) == set(trial["joints"])
    assert {t["column"] for t in trial["trajectory"].values()} == set(trial["joints"])
    # devices per joint: the knee's elements and the ankle's, none on the hip
    joints = {e["joint"] for e in trial["device"]}
    assert joints == {"knee_flexion", "ankle_flexion"}
    cal = plan.to_json()["steps"][0]
    assert cal["joints"] == trial["joints"]
    assert cal["trajectory"]["ankle_flexion"]["from_deg"] == -20.0
    fits = [s for s in plan.to_json()["steps"] if s["kind"] == "fit"]
    assert [s["id"] for s in fits] == ["fit:k01", "fit:k02", "fit:k03"]  # per joint carrying elements


def test_single_joint_plans_keep_their_shape() -> None:
    for name in ("knee_phase1.yaml", "ankle_phase2.yaml"):
        plan = expand(load_protocol(REPO / "protocols" / name)).to_json()
        trials = [s for s in plan["steps"] if s["kind"] == "trial"]
        assert all("joints" not in s and "profile" in s["trajectory"] for s in trials)
        assert all("joint" not in e for s in trials if s["brace"] == "on" for e in s["device"])


def test_per_joint_trajectory_kind(workdir: Path) -> None:
    text = LEG_TEXT.replace(
        "  sit_to_stand: {kind: file, file: trajectories/leg_sit_to_stand_synthetic.csv}",
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        "      hip_flexion: {kind: sinusoid, range_deg: [10, 40], speed_deg_s: 15, periods: 2}\n"
        "      knee_flexion: {kind: sinusoid, range_deg: [20, 90], speed_deg_s: 35, periods: 2}\n"
        "      ankle_flexion: {kind: sinusoid, range_deg: [-10, 10], speed_deg_s: 10, periods: 2}",
    )
    path = workdir / "leg_per_joint.yaml"
    path.write_text(text, encoding="utf-8")
    steps = [
        s for s in expand(load_protocol(path)).steps if isinstance(s, TrialStep) and s.configuration == 3
    ]
    motion = dict(steps[0].joint_trajectories)
    assert motion["knee_flexion"].profile == "sinusoid" and motion["knee_flexion"].amplitude_deg == 35.0
    assert motion["hip_flexion"].period_s == pytest.approx(motion["knee_flexion"].period_s)


def _csv(workdir: Path, rows: list[str], name: str = "bad.csv") -> None:
    (workdir / "trajectories" / name).write_text("# test file\n" + "\n".join(rows) + "\n", encoding="utf-8")


def _with_file(workdir: Path, name: str = "bad.csv") -> Path:
    path = workdir / "leg_bad.yaml"
    path.write_text(LEG_TEXT.replace(GAIT, f"trajectories/{name}"), encoding="utf-8")
    return path


def test_missing_joint_column_names_file_line_and_joint(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _csv(workdir, ["time_s,hip_flexion,knee_flexion", "0,20,45", "0.01,20,45"])
    err = _refused(_with_file(workdir), capsys)
    assert "bad.csv:2" in err and "ankle_flexion" in err and "leg_bad.yaml:" in err


def test_uneven_columns_name_line_and_columns(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _csv(workdir, ["time_s,hip_flexion,knee_flexion,ankle_flexion", "0,20,45,0", "0.01,20,45"])
    err = _refused(_with_file(workdir), capsys)
    assert "bad.csv:4" in err and "ankle_flexion" in err


def test_non_monotonic_time_is_refused(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _csv(
        workdir,
        ["time_s,hip_flexion,knee_flexion,ankle_flexion", "0,20,45,0", "0.02,20,45,0", "0.01,20,45,0"],
    )
    err = _refused(_with_file(workdir), capsys)
    assert "bad.csv" in err and "increase strictly" in err and "hip_flexion" in err


def test_motion_outside_one_joints_range_names_that_joint(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the ankle goes to -50 deg: outside its Table 2 range [-45, 30]; hip and knee are fine
    rows = ["time_s,hip_flexion,knee_flexion,ankle_flexion"]
    rows += [f"{i / 100:.2f},20,45,{-50 * i / 400:.4f}" for i in range(401)]
    _csv(workdir, rows)
    err = _refused(_with_file(workdir), capsys)
    assert "joint ankle_flexion" in err and "the joint allows -45 to 30 deg" in err
    assert (
        "bad.csv line 402 column ankle_flexion" in err
    )  # t = 3.99 s: row 399 after a comment and the header
    assert "joint knee_flexion" not in err and "joint hip_flexion" not in err


def test_one_joints_rate_limit_is_its_own(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the knee moves 95 deg/s: under the rig's 120 but over this protocol's knee limit of 90
    text = LEG_TEXT.replace(
        "max_rate_deg_s: 100, park_angle_deg: 45", "max_rate_deg_s: 50, park_angle_deg: 45"
    )
    path = workdir / "leg_rate.yaml"
    path.write_text(text, encoding="utf-8")
    err = _refused(path, capsys)
    assert "joint knee_flexion" in err and "max_rate_deg_s" in err


def test_two_driven_joints_on_one_channel(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = (REPO / "src" / "protocol_runner" / "rigs" / "rsst.yaml").read_text(encoding="utf-8")
    (workdir / "rig.yaml").write_text(rig, encoding="utf-8")
    # a rig file cannot put two joints on one channel (refused naming the rig file's line) ...
    bad = rig.replace("    output_channel: 10\n", "    output_channel: 8\n", 1)
    (workdir / "bad_rig.yaml").write_text(bad, encoding="utf-8")
    path = workdir / "leg_rig.yaml"
    path.write_text(LEG_TEXT.replace("rig: rsst", "rig: bad_rig.yaml"), encoding="utf-8")
    err = _refused(path, capsys)
    assert "bad_rig.yaml:" in err and "output channel 8" in err and "knee_flexion" in err
    # ... and a joint listed twice is refused at `joints`
    path.write_text(
        LEG_TEXT.replace(
            "joints: [hip_flexion, knee_flexion, ankle_flexion]",
            "joints: [hip_flexion, knee_flexion, knee_flexion]",
        ),
        encoding="utf-8",
    )
    err = _refused(path, capsys)
    assert "leg_rig.yaml:" in err and "listed twice" in err


def test_per_joint_trajectory_missing_a_joint_and_unequal_lengths(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = "  sit_to_stand: {kind: file, file: trajectories/leg_sit_to_stand_synthetic.csv}"
    missing = LEG_TEXT.replace(
        base,
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        "      hip_flexion: {kind: sinusoid, range_deg: [10, 40], speed_deg_s: 15, periods: 2}",
    )
    path = workdir / "leg_pj.yaml"
    path.write_text(missing, encoding="utf-8")
    err = _refused(path, capsys)
    assert "no entry for driven joint(s) knee_flexion, ankle_flexion" in err
    unequal = LEG_TEXT.replace(
        base,
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        "      hip_flexion: {kind: hold, angle_deg: 20, duration_s: 10}\n"
        "      knee_flexion: {kind: hold, angle_deg: 45, duration_s: 10}\n"
        "      ankle_flexion: {kind: hold, angle_deg: 0, duration_s: 12}",
    )
    path.write_text(unequal, encoding="utf-8")
    err = _refused(path, capsys)
    assert "share its time" in err and "ankle_flexion 1200" in err


def test_override_and_device_of_an_undriven_joint_are_refused(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = workdir / "leg_x.yaml"
    path.write_text(
        LEG_TEXT.replace("    hip_flexion:\n      safety:", "    elbow_flexion:\n      safety:"),
        encoding="utf-8",
    )
    err = _refused(path, capsys)
    assert "elbow_flexion" in err and "not one of the driven joints" in err


def test_park_against_a_joints_stop_names_the_joint(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = workdir / "leg_park.yaml"
    path.write_text(
        LEG_TEXT.replace("ankle: {range_deg: [-38, 24]", "ankle: {range_deg: [5, 24]"), encoding="utf-8"
    )
    err = _refused(path, capsys)
    assert "joint ankle_flexion's park angle 0 deg is outside the stops" in err


def test_plan_json_round_trip_through_cli(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--json", "--plan", str(LEG)]) == 0
    plan = json.loads(capsys.readouterr().out)
    trial = next(s for s in plan["steps"] if s["kind"] == "trial")
    assert list(trial["trajectory"]) == trial["joints"]


def test_joint_and_joints_together_are_refused(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = workdir / "leg_jj.yaml"
    path.write_text(LEG_TEXT.replace("rig: rsst\n", "rig: rsst\njoint: knee_flexion\n"), encoding="utf-8")
    err = _refused(path, capsys)
    assert "exactly one of `joint`" in err
