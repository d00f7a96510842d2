"""Preflight: `--validate` runs exactly the run's checks, hostile files get
bounded work and one located message (exit 2), and no session folder is created when preflight fails."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.cli import main
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.resources import packaged_protocols_dir
from protocol_runner.session.setup import create_session

from .test_broken_files import KNEE_TEXT, line_of, workdir, write

__all__ = ["workdir"]  # the fixture, imported for pytest

SECRET = "TOP-SECRET-LINE-do-not-print"


def refused_everywhere(path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """`--validate` and a dry run both exit 2 with the same message; the run creates no session folder."""
    assert main(["--validate", str(path)]) == 2
    validate_err = capsys.readouterr().err
    session = tmp_path / "session"
    assert main([str(path), "--dry-run", "--yes", "--session", str(session)]) == 2
    run_err = capsys.readouterr().err
    assert not session.exists(), "a session folder was created although preflight failed"
    assert validate_err == run_err
    assert "Traceback" not in run_err and SECRET not in run_err
    return run_err


def fast_human_file(path: Path) -> None:
    """A triangle wave at 50 deg/s (within the 120 deg/s rate limit) whose corners need 10,000 deg/s^2."""
    t = np.arange(0.0, 10.0, 0.01)
    angle = 60.0 + 30.0 * (2.0 / np.pi) * np.arcsin(np.sin(2.0 * np.pi * t / 2.4))
    rows = "".join(f"{a:.2f},{b:.4f}\n" for a, b in zip(t, angle, strict=True))
    path.write_text("# triangle wave\ntime_s,angle_deg\n" + rows, encoding="utf-8")


def test_human_file_over_the_acceleration_limit_is_refused_by_validate_and_run(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fast_human_file(workdir / "trajectories" / "fast.csv")
    text = KNEE_TEXT.replace("subject_C_synthetic.csv", "fast.csv")
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    assert re.search(
        r"broken\.yaml:\d+: trajectories\.subject_C\.file: trajectory 'subject_C' \(file trajectories/fast\.csv\)"
        r".*angular acceleration reaches -1e\+04 deg/s² .*allows ±2000 deg/s² \(configuration 25 in set 'emu_comparison'\)",
        err,
    ), err


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        (
            "max_accel_deg_s2: 2000",
            "max_accel_deg_s2: .inf",
            "rig_overrides.joints.knee_flexion.safety.max_accel_deg_s2",
        ),
        (
            "max_rate_deg_s: 120",
            "max_rate_deg_s: .nan",
            "rig_overrides.joints.knee_flexion.safety.max_rate_deg_s",
        ),
        ("periods: 8", "periods: .inf", "trajectories.sine.periods"),
    ],
)
def test_non_finite_numbers_are_refused(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, field: str
) -> None:
    text = KNEE_TEXT.replace(old, new, 1)
    assert text != KNEE_TEXT
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    assert re.search(rf"broken\.yaml:{line_of(text, new)}: {field}: .*finite number", err), err


def test_a_non_finite_quantity_is_refused(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = KNEE_TEXT.replace("R3: {range_deg: [0, 130]", "R3: {range_deg: [0, .inf]", 1)
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    assert re.search(
        rf"broken\.yaml:{line_of(text, '.inf')}: factors\.brace_rom\.R3: .*must be finite", err
    ), err


@pytest.mark.parametrize(
    ("old", "field"),
    [
        ("calibration/knee_command.csv", "rig_overrides.joints.knee_flexion.calibration.command_table"),
        ("calibration/knee_torque.csv", "rig_overrides.joints.knee_flexion.calibration.torque_table"),
    ],
)
def test_referenced_file_outside_the_folder_is_refused_without_quoting_it(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, field: str
) -> None:
    (workdir.parent / "secret.txt").write_text(SECRET + "\n", encoding="utf-8")
    text = KNEE_TEXT.replace(old, "../secret.txt")
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    line = line_of(text, "../secret.txt")
    assert f"broken.yaml:{line}: {field}: ../secret.txt lies outside the protocol's folder" in err, err


def test_trajectory_file_outside_the_folder_is_refused_without_quoting_it(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (workdir.parent / "secret.txt").write_text(SECRET + "\n", encoding="utf-8")
    text = KNEE_TEXT.replace("trajectories/subject_B_synthetic.csv", "../secret.txt")
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    line = line_of(text, "{key: 24, run: 24,")
    assert (
        f"broken.yaml:{line}: sets[8].configurations[0].trajectory: trajectory 'subject_B': file: " in err
    ), err
    assert "lies outside the protocol's folder" in err and SECRET not in err


def test_reference_dataset_outside_the_folder_is_refused(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (workdir.parent / "secret.txt").write_text(SECRET + "\n", encoding="utf-8")
    text = KNEE_TEXT.replace("reference_dataset: null", "reference_dataset: ../secret.txt", 1)
    assert text != KNEE_TEXT
    err = refused_everywhere(write(workdir, text), tmp_path, capsys)
    line = line_of(text, "../secret.txt")
    assert (
        f"broken.yaml:{line}: report.reference_dataset: ../secret.txt lies outside the protocol's folder"
        in err
    )


def test_symlink_and_absolute_path_out_of_the_folder_are_refused(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    secret = tmp_path / "secret.csv"
    secret.write_text(SECRET + "\n", encoding="utf-8")
    (workdir / "calibration" / "link.csv").symlink_to(secret)
    linked = KNEE_TEXT.replace("calibration/knee_command.csv", "calibration/link.csv")
    err = refused_everywhere(write(workdir, linked), tmp_path, capsys)
    assert (
        "rig_overrides.joints.knee_flexion.calibration.command_table: calibration/link.csv lies outside "
        "the protocol's folder" in err
    )
    absolute = KNEE_TEXT.replace("calibration/knee_command.csv", str(secret))
    err = refused_everywhere(write(workdir, absolute), tmp_path, capsys)
    assert f"{secret} is an absolute path outside the shipped protocols" in err, err


def test_a_shipped_table_may_be_named_by_its_absolute_path(workdir: Path, tmp_path: Path) -> None:
    shipped = packaged_protocols_dir() / "calibration" / "knee_command.csv"
    path = write(workdir, KNEE_TEXT.replace("calibration/knee_command.csv", str(shipped)))
    loaded = load_protocol(path)
    info = create_session(tmp_path / "s", loaded, mode="dry-run", seed=0, only=(), realtime=False)
    assert info.protocol_sha256 == loaded.sha256
    assert (tmp_path / "s" / "protocol" / "calibration" / "knee_angle.csv").is_file()


# ------------------------------------------------------------------------------- bounded work (7)


def refused_quickly(path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    start = time.monotonic()
    err = refused_everywhere(path, tmp_path, capsys)
    assert time.monotonic() - start < 20.0
    return err


def test_alias_bomb_is_refused_before_it_expands(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = ['a: &a ["x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for i in range(1, 10):  # 9^10 values when expanded
        prev, name = chr(96 + i), chr(97 + i)
        rows.append(f"{name}: &{name} [{', '.join([f'*{prev}'] * 9)}]")
    text = KNEE_TEXT + "\n".join(rows) + "\n"
    err = refused_quickly(write(workdir, text), tmp_path, capsys)
    assert re.search(r"broken\.yaml:\d+: the YAML expands to more than 200,000 values", err), err
    line = int(re.search(r"broken\.yaml:(\d+):", err).group(1))  # type: ignore[union-attr]
    assert line > KNEE_TEXT.count("\n")  # the line is in the alias rows


def test_deep_nesting_is_refused_without_recursion_error(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = KNEE_TEXT + "deep: " + "[" * 200_000 + "]" * 200_000 + "\n"
    err = refused_quickly(write(workdir, text), tmp_path, capsys)
    assert f"broken.yaml:{line_of(text, 'deep: [[[')}: the YAML nests deeper than 40 levels" in err, err


def test_recursive_alias_is_refused(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = KNEE_TEXT + "loop: &loop [1, *loop]\n"
    err = refused_quickly(write(workdir, text), tmp_path, capsys)
    assert f"broken.yaml:{line_of(text, 'loop: &loop')}: alias *loop repeats a collection" in err, err


def test_oversized_file_is_refused_without_reading_it_all(
    workdir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = KNEE_TEXT + ("# padding\n" * 200_000)
    err = refused_quickly(write(workdir, text), tmp_path, capsys)
    assert "broken.yaml: the file is larger than 1000 kB" in err, err


@pytest.mark.parametrize(
    ("only", "needle"),
    [
        ("4-400000000", "no configuration has key 29, 30, 31, 32, 33 and 399,999,967 more"),
        ("0-9999999999999", "no configuration has key 0, 29, 30, 31, 32 and "),
        ("12,99", "no configuration has key 99 (keys in knee_phase1.yaml: 1-28)"),
    ],
)
def test_only_is_checked_against_the_matrix_without_materialising_ranges(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], only: str, needle: str
) -> None:
    session = tmp_path / "session"
    start = time.monotonic()
    assert main(["knee_phase1.yaml", "--dry-run", "--yes", "--only", only, "--session", str(session)]) == 2
    assert time.monotonic() - start < 20.0
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err, err
    assert not session.exists()


def test_alias_count_and_depth_through_aliases_are_capped(workdir: Path) -> None:
    from protocol_runner.errors import InvalidInput
    from protocol_runner.protocol.yaml_limits import MAX_ALIASES, check_yaml_limits

    many = "a: &a 1\nb: [" + ", ".join(["*a"] * (MAX_ALIASES + 1)) + "]\n"
    with pytest.raises(InvalidInput, match=rf"^many\.yaml:2: more than {MAX_ALIASES} YAML aliases"):
        check_yaml_limits(many, "many.yaml")
    deep = "a: &a " + "[" * 30 + "]" * 30 + "\n" + "b: " + "[" * 20 + "*a" + "]" * 20 + "\n"
    with pytest.raises(InvalidInput, match=r"^deep\.yaml:2: the YAML nests deeper than 40 levels \(through"):
        check_yaml_limits(deep, "deep.yaml")
    check_yaml_limits(KNEE_TEXT, "knee_phase1.yaml")  # the shipped protocol is far inside every limit
