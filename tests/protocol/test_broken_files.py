"""A corpus of broken protocol files: each gets one short message naming file, line and field, exit 2."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import load_protocol

REPO = Path(__file__).resolve().parents[2]
KNEE = REPO / "protocols" / "knee_phase1.yaml"
KNEE_TEXT = KNEE.read_text(encoding="utf-8")


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    """A copy of the protocols directory, so relative trajectory/calibration paths resolve."""
    shutil.copytree(REPO / "protocols", tmp_path / "protocols")
    return tmp_path / "protocols"


def line_of(text: str, needle: str, occurrence: int = 1) -> int:
    count = 0
    for i, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            count += 1
            if count == occurrence:
                return i
    raise AssertionError(f"{needle!r} not in text")


def write(workdir: Path, text: str, name: str = "broken.yaml") -> Path:
    path = workdir / name
    path.write_text(text, encoding="utf-8")
    return path


def error_of(path: Path) -> str:
    with pytest.raises(InvalidInput) as info:
        load_protocol(path, display_name=path.name)
    return info.value.message


# (name, edit of the good text, expected message regex, the line's needle in the edited text or None)
CASES = [
    (
        "unknown friction level",
        lambda t: t.replace('friction: "3", stiffness: K2', 'friction: "5", stiffness: K2'),
        r"sets\[3\]\.configurations\[3\]\.friction: unknown level '5' \(known: 0, 1, 2, 3, EMU\)",
        'friction: "5"',
    ),
    (
        "unknown key",
        lambda t: t.replace("    periods: 8", "    periods: 8\n    perods: 9"),
        r"trajectories\.sinusoid\.perods: unknown key \(allowed: periods\)",
        "perods: 9",
    ),
    (
        "wrong type",
        lambda t: t.replace("    rate_hz: 100 ", "    rate_hz: fast "),
        r"rig\.output\.rate_hz: .*number.*\(got 'fast'\)",
        "rate_hz: fast",
    ),
    (
        "out of the joint's range",
        lambda t: t.replace("R3: {range_deg: [0, 130]}", "R3: {range_deg: [0, 150]}"),
        r"levels\.brace_rom\.R3\.range_deg: \[0, 150\] deg is outside the joint's range \[0, 130\] deg",
        "R3: {range_deg: [0, 150]}",
    ),
    (
        "trial count zero",
        lambda t: t.replace("preload: Center, trials: 3}", "preload: Center, trials: 0}", 1),
        r"sets\[0\]\.configurations\[0\]\.trials: .*greater than or equal to 1",
        "trials: 0}",
    ),
    (
        "duplicate key",
        lambda t: t.replace("{key: 11, run: 2,", "{key: 10, run: 2,"),
        r"sets\[0\]\.configurations\[1\]\.key: key 10 is already used by sets\[0\]\.configurations\[0\]",
        "{key: 10, run: 2,",
    ),
    (
        "duplicate run number",
        lambda t: t.replace("{key: 11, run: 2,", "{key: 11, run: 1,"),
        r"sets\[0\]\.configurations\[1\]\.run: test run 1 is already used",
        "{key: 11, run: 1,",
    ),
    (
        "missing trajectory file",
        lambda t: t.replace("subject_C_synthetic.csv", "subject_C_missing.csv"),
        r"trajectories\.human\.subject_C\.file: .*subject_C_missing\.csv: trajectory file not found",
        "subject_C_missing.csv",
    ),
    (
        "unknown trajectory name",
        lambda t: t.replace("trajectory: subject_E,", "trajectory: subject_Z,"),
        r"configurations\[2\]\.trajectory: unknown trajectory 'subject_Z' \(known: subject_B, subject_C, subject_E\)",
        "subject_Z",
    ),
    (
        "speed above the rate limit",
        lambda t: t.replace("Full: {max_deg_s: 50.0}", "Full: {max_deg_s: 500.0}"),
        r"sets\[0\]\.configurations\[0\]\.speed: 500 deg/s exceeds the rig's rate limit",
        "{key: 10, run: 1,",
    ),
    (
        "YAML syntax",
        lambda t: t.replace("  robot: RSST", "  robot: [RSST"),
        r"YAML syntax error",
        None,
    ),
    (
        "missing required section",
        lambda t: re.sub(r"\nprocessing:.*?\n\n", "\n\n", t, flags=re.S),
        r"processing: required field is missing",
        None,
    ),
    (
        "alias to an unknown level",
        lambda t: t.replace('EMU: {same_as: "2"', 'EMU: {same_as: "9"'),
        r"levels\.friction\.EMU\.same_as: unknown level '9'",
        'same_as: "9"',
    ),
    (
        "prediction of a missing configuration",
        lambda t: t.replace("{fit: 12, predict: 14,", "{fit: 12, predict: 99,"),
        r"report\.predictions\[1\]\.predict: no configuration has key 99",
        "predict: 99",
    ),
    (
        "comparison of a missing configuration",
        lambda t: t.replace("configurations: [10, 11]}", "configurations: [10, 99]}"),
        r"report\.comparisons\[0\]\.configurations\[1\]: no configuration has key 99",
        "configurations: [10, 99]}",
    ),
    (
        "boolean where a key belongs",
        lambda t: t.replace("{key: 10, run: 1,", "{key: true, run: 1,"),
        r"sets\[0\]\.configurations\[0\]\.key: input should be a valid integer \(got True\)",
        "{key: true, run: 1,",
    ),
    (
        "unknown profile",
        lambda t: t.replace("{key: 27, run: 27, profile: sinusoid", "{key: 27, run: 27, profile: triangle"),
        r"profile: input should be 'sinusoid', 'human' or 'identification'",
        "profile: triangle",
    ),
]


@pytest.mark.parametrize(("name", "edit", "pattern", "needle"), CASES, ids=[c[0] for c in CASES])
def test_broken_file_gets_a_located_message(
    workdir: Path, name: str, edit, pattern: str, needle: str | None
) -> None:
    text = edit(KNEE_TEXT)
    assert text != KNEE_TEXT, "the edit must change the file"
    message = error_of(write(workdir, text))
    assert re.search(pattern, message), message
    assert message.startswith("broken.yaml:"), message
    if needle is not None:
        assert message.startswith(f"broken.yaml:{line_of(text, needle)}:"), message
    assert "Traceback" not in message and len(message.splitlines()) <= 9


def test_empty_file(workdir: Path) -> None:
    assert "the file is empty" in error_of(write(workdir, "# only a comment\n\n"))


def test_top_level_not_a_mapping(workdir: Path) -> None:
    assert "top level must be a mapping" in error_of(write(workdir, "- just\n- a list\n"))


def test_binary_garbage(workdir: Path) -> None:
    path = workdir / "garbage.yaml"
    path.write_bytes(bytes(range(256)) * 4)
    assert "binary file" in error_of(path)


def test_not_utf8(workdir: Path) -> None:
    path = workdir / "latin1.yaml"
    path.write_bytes("name: caf\xe9\n".encode("latin-1"))
    assert re.search(r"latin1\.yaml:1: not valid UTF-8", error_of(path))


def test_a_directory(workdir: Path) -> None:
    assert "is a directory" in error_of(workdir)


def test_missing_file(tmp_path: Path) -> None:
    assert "not found" in error_of(tmp_path / "nope.yaml")


def test_duplicate_yaml_key(workdir: Path) -> None:
    text = KNEE_TEXT.replace("name: knee_phase1\n", "name: knee_phase1\nname: again\n", 1)
    message = error_of(write(workdir, text))
    assert re.search(rf"broken\.yaml:{line_of(text, 'name: again')}: name: duplicate key", message), message


def test_several_problems_are_all_listed(workdir: Path) -> None:
    text = KNEE_TEXT.replace('friction: "3", stiffness: K2', 'friction: "5", stiffness: K2').replace(
        "stiffness: K3, speed: Full, preload: Center, trials: 3}",
        "stiffness: K9, speed: Full, preload: Center, trials: 3}",
        1,
    )
    message = error_of(write(workdir, text))
    assert "unknown level '5'" in message and "unknown level 'K9'" in message


@pytest.mark.parametrize("mode", ["--validate", "--plan"])
def test_cli_prints_one_paragraph_and_exits_2(
    workdir: Path, capsys: pytest.CaptureFixture[str], mode: str
) -> None:
    path = write(workdir, KNEE_TEXT.replace('friction: "3", stiffness: K2', 'friction: "5", stiffness: K2'))
    assert main([mode, str(path)]) == 2
    err = capsys.readouterr().err
    assert "unknown level '5'" in err and "Traceback" not in err
    line = line_of(path.read_text(), 'friction: "5"')
    assert f":{line}:" in err


def test_park_angle_outside_a_brace_range_is_refused(workdir: Path) -> None:
    text = KNEE_TEXT.replace("park_angle_deg: 45 ", "park_angle_deg: 20 ")
    assert text != KNEE_TEXT
    message = error_of(write(workdir, text))
    assert re.search(
        r"levels\.brace_rom\.R1\.range_deg: the park angle .* 20 deg is outside this brace range", message
    ), message
