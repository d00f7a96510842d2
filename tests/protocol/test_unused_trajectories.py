"""A declared trajectory that no configuration uses is checked all the same (its file confined to the
protocol's folder, present and readable, its constant fields buildable and within the joint's limits),
since the session stores its file and a mistake in it is a mistake in the protocol; and `--validate`
names it, since a motion declared and never run may be a set forgotten."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.resources import packaged_protocols_dir

from ..multi.test_multi_protocol import LEG_TEXT

ELBOW = (packaged_protocols_dir() / "elbow_example.yaml").read_text(encoding="utf-8")
HEAD = "trajectories:\n"


def _elbow_with(tmp_path: Path, declaration: str) -> tuple[Path, int]:
    """elbow_example with `declaration` added as the first trajectory (unused); its line number."""
    assert ELBOW.count(HEAD) == 1
    path = tmp_path / "elbow.yaml"
    path.write_text(ELBOW.replace(HEAD, HEAD + declaration + "\n"), encoding="utf-8")
    return path, ELBOW.splitlines().index(HEAD.strip()) + 2


def _validate(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["--validate", str(path)])
    return code, capsys.readouterr().err


def test_an_unused_file_outside_the_folder_is_refused_at_its_file_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, line = _elbow_with(tmp_path, "  gait: {kind: file, file: ../../etc/passwd}")
    code, err = _validate(path, capsys)
    assert code == 2
    assert f"{path}:{line}: trajectories.gait.file: " in err and "outside the protocol's folder" in err
    assert "root:" not in err  # nothing of the file is shown


def test_the_run_refuses_it_before_creating_a_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, _ = _elbow_with(tmp_path, "  gait: {kind: file, file: /etc/passwd}")
    session = tmp_path / "session"
    assert main([str(path), "--dry-run", "--only", "1", "--session", str(session)]) == 2
    err = capsys.readouterr().err
    assert "trajectories.gait.file" in err and "absolute path outside the shipped protocols" in err
    assert not session.exists()


def test_an_unused_missing_file_is_refused_not_left_to_the_session_copy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The session copies every declared trajectory file: a missing one would stop the run at its start."""
    path, line = _elbow_with(tmp_path, "  gait: {kind: file, file: gait.csv}")
    code, err = _validate(path, capsys)
    assert code == 2 and f"{path}:{line}: trajectories.gait.file: " in err and "gait.csv" in err
    assert "not found" in err


def test_an_unused_triangle_that_cannot_reach_its_speed_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path, line = _elbow_with(
        tmp_path,
        "  quick: {kind: triangle, range_deg: [20, 22], speed_deg_s: 60, cycles: 2, corner_accel_deg_s2: 200}",
    )
    code, err = _validate(path, capsys)
    assert code == 2 and f"{path}:{line}: trajectories.quick: " in err and "cannot be reached" in err


def test_a_sound_unused_trajectory_passes_and_validate_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Named in --validate's summary, not as a warning on every run: a campaign may keep a motion declared
    for a later set (knee_phase1's Eq 4-7 identification motion)."""
    path, _ = _elbow_with(tmp_path, "  spare: {kind: hold, angle_deg: 40, duration_s: 10}")
    assert main(["--validate", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "Declared but used by no configuration: 1 trajectory (spare)." in out and err == ""
    text = path.read_text(encoding="utf-8").replace("trajectory: sine", "trajectory: spare", 1)
    path.write_text(text, encoding="utf-8")
    assert main(["--validate", str(path)]) == 0
    assert "Declared but used" not in capsys.readouterr().out


def test_the_knee_campaigns_unused_identification_motion_is_checked_against_the_joints_limits(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Its last period of 3.2 s keeps it within the knee's 120 deg/s; 1.5 s would not."""
    protocols = Path(__file__).resolve().parents[2] / "protocols"
    text = (protocols / "knee_phase1.yaml").read_text(encoding="utf-8")
    assert main(["--validate", str(protocols / "knee_phase1.yaml")]) == 0
    assert "used by no configuration: 1 trajectory (identification)" in capsys.readouterr().out
    for name in ("trajectories", "calibration"):
        (tmp_path / name).symlink_to(protocols / name)
    path = tmp_path / "knee.yaml"
    path.write_text(text.replace("final_period_s: 3.2 ", "final_period_s: 1.5 "), encoding="utf-8")
    code, err = _validate(path, capsys)
    assert code == 2 and "trajectories.identification.final_period_s: " in err and "allows" in err


def test_a_multi_joint_unused_entry_is_located_at_its_joint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "trajectories").symlink_to(Path(__file__).resolve().parents[2] / "protocols" / "trajectories")
    spare = (
        "  spare:\n    kind: per_joint\n    joints:\n"
        "      hip_flexion: {kind: hold, angle_deg: 20, duration_s: 10}\n"
        "      knee_flexion: {kind: file, file: ../knee.csv}\n"
        "      ankle_flexion: {kind: hold, angle_deg: 0, duration_s: 10}\n"
    )
    path = tmp_path / "leg.yaml"
    path.write_text(LEG_TEXT.replace(HEAD, HEAD + spare), encoding="utf-8")
    line = LEG_TEXT.splitlines().index(HEAD.strip()) + 6
    code, err = _validate(path, capsys)
    assert code == 2
    assert f"{path}:{line}: trajectories.spare.joints.knee_flexion.file: " in err and "outside" in err
