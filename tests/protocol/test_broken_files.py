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
        "unknown factor in a configuration",
        lambda t: t.replace(
            "{key: 11, run: 2, trajectory: sine,", "{key: 11, run: 2, trajectory: sine, colour: red,"
        ),
        r"sets\[0\]\.configurations\[1\]\.colour: unknown factor 'colour' \(declared factors: brace_rom, ",
        "colour: red",
    ),
    (
        "unknown key",
        lambda t: t.replace("    periods: 8 ", "    perods: 9\n    periods: 8 "),
        r"trajectories\.sine\.perods: unknown key",
        "perods: 9",
    ),
    (
        "unknown report part cited",
        lambda t: t.replace('    energy: "thesis Figures 41-46"', '    energie: "thesis Figures 41-46"'),
        r"report\.citations\.energie: unknown key",
        "energie:",
    ),
    (
        "wrong type",
        lambda t: t.replace("        max_rate_deg_s: 120 ", "        max_rate_deg_s: fast "),
        r"rig_overrides\.joints\.knee_flexion\.safety\.max_rate_deg_s: .*number.*\(got 'fast'\)",
        "max_rate_deg_s: fast",
    ),
    (
        "out of the joint's range",
        lambda t: t.replace("R3: {range_deg: [0, 130]", "R3: {range_deg: [0, 150]"),
        r"factors\.brace_rom\.R3\.range_deg: \[0, 150\] deg is outside the joint's range \[0, 130\] deg",
        "R3: {range_deg: [0, 150]",
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
        r"sets\[8\]\.configurations\[1\]\.trajectory: .*subject_C_missing\.csv.*not found",
        "{key: 25, run: 25,",
    ),
    (
        "unknown trajectory name",
        lambda t: t.replace("trajectory: subject_E,", "trajectory: subject_Z,"),
        r"configurations\[2\]\.trajectory: unknown trajectory 'subject_Z' \(known: sine, subject_B, ",
        "subject_Z",
    ),
    (
        "speed above the rate limit",
        lambda t: t.replace("Full: {speed_deg_s: 50.0}", "Full: {speed_deg_s: 500.0}"),
        r"trajectories\.sine\.speed_deg_s: trajectory 'sine' \(sinusoid\): speed_deg_s \(bound to "
        r"speed\.speed_deg_s\): its peak speed \(Eq 25\) 500 deg/s is over the joint's rate limit "
        r"max_rate_deg_s = 120 deg/s \(configurations 1-10, 12-23, 27\)",
        "speed_deg_s: speed.speed_deg_s",
    ),
    (
        "YAML syntax",
        lambda t: t.replace("rig: rsst ", "rig: [rsst "),
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
        r"factors\.friction\.EMU\.same_as: unknown level '9'",
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
        "comparison of an undeclared parameter",
        lambda t: t.replace("parameter: speed, section", "parameter: velocity, section", 1),
        r"report\.comparisons\[0\]\.parameter: unknown parameter 'velocity': a declared factor",
        "parameter: velocity",
    ),
    (
        "boolean where a key belongs",
        lambda t: t.replace("{key: 10, run: 1,", "{key: true, run: 1,"),
        r"sets\[0\]\.configurations\[0\]\.key: input should be a valid integer \(got True\)",
        "{key: true, run: 1,",
    ),
    # --- bad input -----------------------------------------------------------------------------------------
    (
        "unknown element type",
        lambda t: t.replace("type: rom_stops", "type: rom_stop"),
        r"device\.elements\[0\]\.type: unknown element type 'rom_stop'; did you mean 'rom_stops'\? \(known: lever_spring, ",
        "type: rom_stop",
    ),
    (
        "unknown element parameter",
        lambda t: t.replace("      slack_deg: 13.0 ", "      slack_degrees: 13.0 "),
        r"device\.elements\[0\]\.slack_degrees: unknown parameter of rom_stops",
        "slack_degrees: 13.0",
    ),
    (
        "missing required element parameter",
        lambda t: t.replace("      stop_stiffness_nm_per_deg: 40.0 ", "      "),
        r"device\.elements\[0\]: missing required parameter 'stop_stiffness_nm_per_deg' of rom_stops",
        "- name: stops",
    ),
    (
        "unknown trajectory kind",
        lambda t: t.replace("kind: sinusoid", "kind: sinewave"),
        r"trajectories\.sine: unknown kind 'sinewave' \(known: 'sinusoid', 'triangle', ",
        "sine:",
    ),
    (
        "binding to an undeclared factor",
        lambda t: t.replace("torque_nm: friction.friction_nm", "torque_nm: brakes.friction_nm"),
        r"device\.elements\[1\]\.torque_nm: bound to brakes\.friction_nm: no factor 'brakes' is declared",
        "torque_nm: brakes.friction_nm",
    ),
    (
        "binding to a level without the quantity",
        lambda t: t.replace('"3": {friction_nm: 6.25,', '"3": {torque_nm: 6.25,'),
        r"device\.elements\[1\]\.torque_nm: bound to friction\.friction_nm but level '3' of friction has no "
        r"'friction_nm' \(it has torque_nm, screw_turns\) \(configuration 7 in set 'friction'\)",
        "torque_nm: friction.friction_nm",
    ),
    (
        "binding with the wrong unit",
        lambda t: t.replace("speed_deg_s: speed.speed_deg_s", "speed_deg_s: friction.friction_nm"),
        r"trajectories\.sine\.speed_deg_s: bound to friction\.friction_nm, whose unit suffix is _nm; this "
        r"parameter needs a quantity ending with _deg_s",
        "speed_deg_s: friction.friction_nm",
    ),
    (
        "quantity without a unit suffix",
        lambda t: t.replace("Full: {speed_deg_s: 50.0}", "Full: {speed: 50.0}"),
        r"factors\.speed\.Full: 'speed': a quantity's name must end with a unit suffix \(_nm_s_per_deg, ",
        "Full: {speed: 50.0}",
    ),
    (
        "joint not on the rig",
        lambda t: t.replace("joint: knee_flexion ", "joint: knee_bending "),
        r"joint: no joint 'knee_bending' on rig RSST \(joints: shoulder_flexion, ",
        "joint: knee_bending",
    ),
    (
        "unknown rig",
        lambda t: t.replace("rig: rsst ", "rig: rsstt "),
        r"rig: unknown rig 'rsstt' \(shipped rigs: rsst; or give a path\)",
        "rig: rsstt",
    ),
    (
        "override wider than the rig",
        lambda t: t.replace("        max_rate_deg_s: 120 ", "        max_rate_deg_s: 200 "),
        r"rig_overrides\.joints\.knee_flexion\.safety\.max_rate_deg_s: 200 is above the rig's 120 "
        r"\(rigs/rsst\.yaml\): overrides may only tighten",
        "max_rate_deg_s: 200",
    ),
    (
        "generator over an unknown level",
        lambda t: t.replace(
            "  - name: speed\n    condition: Speed\n",
            "  - name: extra\n    condition: Extra\n    full_factorial:\n      factors: {friction: ['0', '7']}\n"
            "      fixed: {brace_rom: R3, robot_rom: Rr3, stiffness: K2, speed: Full, preload: Center}\n"
            "      trajectory: sine\n      trials: 1\n  - name: speed\n    condition: Speed\n",
        ),
        r"sets\[0\]\.full_factorial\.factors\.friction\[1\]: unknown level '7' of friction",
        "factors: {friction: ['0', '7']}",
    ),
]


# Mistakes that each get exactly one line: no second alternative of a union, no class names, no repeats.
ONE_LINE_CASES = [
    (
        "a boolean for the number of periods",
        lambda t: t.replace("    periods: 8 ", "    periods: yes"),
        r"^broken\.yaml:\d+: trajectories\.sine\.periods: expected a number, got True \(YAML reads yes, no, on, "
        r"off, true and false as booleans\)$",
        "periods: yes",
    ),
    (
        "a boolean in the calibration step",
        lambda t: t.replace("  hold_s: 4.0\n", "  hold_s: on\n"),
        r"^broken\.yaml:\d+: calibration_step\.hold_s: expected a number, got True",
        "hold_s: on",
    ),
    (
        "a boolean in a list of numbers",
        lambda t: t.replace("  time_constant_s: [0.1, 0.35]", "  time_constant_s: [0.1, true]"),
        r"^broken\.yaml:\d+: calibration_check\.time_constant_s\[1\]: expected a number, got True",
        "time_constant_s: [0.1, true]",
    ),
    (
        "a negative hold of the calibration step",
        lambda t: t.replace("  hold_s: 4.0\n", "  hold_s: -4.0\n"),
        r"^broken\.yaml:\d+: calibration_step\.hold_s: input should be greater than 0 \(got -4\.0\)$",
        "hold_s: -4.0",
    ),
    (
        "a calibration step that is a number",
        lambda t: t.replace(
            "calibration_step:                    # Appendix A",
            "calibration_step: 5\nunused_calibration_step:  # Appendix A",
        ),
        r"^broken\.yaml:\d+: calibration_step: input should be a mapping with keys from_deg, step_deg, ramp_s, "
        r"hold_s, settle_s \(got 5\)",
        "calibration_step: 5",
    ),
    (
        "a negative speed says what it got once",
        lambda t: t.replace("    speed_deg_s: speed.speed_deg_s\n", "    speed_deg_s: -30\n", 1),
        r"^broken\.yaml:\d+: trajectories\.sine\.speed_deg_s: must be greater than 0, got -30$",
        "speed_deg_s: -30",
    ),
]


@pytest.mark.parametrize(
    ("name", "edit", "pattern", "needle"), ONE_LINE_CASES, ids=[c[0] for c in ONE_LINE_CASES]
)
def test_a_mistake_gets_one_line_at_its_field(
    workdir: Path, name: str, edit, pattern: str, needle: str
) -> None:
    text = edit(KNEE_TEXT)
    assert text != KNEE_TEXT, "the edit must change the file"
    message = error_of(write(workdir, text))
    lines = message.splitlines()
    assert len(lines) == 1 or name == "a calibration step that is a number", message
    assert re.search(pattern, lines[0]), message
    assert lines[0].startswith(f"broken.yaml:{line_of(text, needle)}:"), message
    assert "Spec" not in message and "Traceback" not in message


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
    first = message.splitlines()[0]
    assert re.search(
        r"sets\[2\]\.configurations\[0\]: the park angle 20 deg is outside the stops "
        r"\[40, 90\] deg of element 'stops'.*\(configuration 1 in set 'brace_rom'\)$",
        first,
    ), message
    assert first.startswith(f"broken.yaml:{line_of(text, '{key: 1, run: 5,')}:")


def test_keys_that_do_not_line_up_name_both_lines(workdir: Path) -> None:
    text = KNEE_TEXT.replace("    R1: {range_deg: [40, 90]", "   R1: {range_deg: [40, 90]", 1)
    assert text != KNEE_TEXT
    first, found = line_of(text, "   R1: {range_deg: [40, 90]"), line_of(text, "    R2: {range_deg")
    message = error_of(write(workdir, text))
    assert message.startswith(f"broken.yaml:{found}: YAML syntax error: "), message
    assert message.endswith(
        f"(the keys of one mapping must line up: compare the indentation of lines {first} and {found})"
    ), message


def test_a_key_indented_too_deep_gets_a_hint_at_its_line(workdir: Path) -> None:
    text = KNEE_TEXT.replace("  from_deg: 20\n  step_deg: 45", "  from_deg: 20\n   step_deg: 45")
    assert text != KNEE_TEXT
    found = line_of(text, "   step_deg: 45")
    message = error_of(write(workdir, text))
    assert message.startswith(
        f"broken.yaml:{found}: YAML syntax error: mapping values are not allowed here"
    ), message
    assert f"compare the indentation of line {found} with the line above, or quote the value)" in message


def test_a_file_trajectory_of_a_billion_seconds_is_refused_before_it_is_sampled(workdir: Path) -> None:
    """Its last row at t = 1e9 s once made --validate ask for 745 GiB (a traceback): its length is checked
    before anything is sampled."""
    rows = "time_s,angle_deg\n0,45.0\n0.01,45.0\n1e9,45.0\n"
    (workdir / "trajectories" / "long.csv").write_text("# a typo in the last time\n" + rows, encoding="utf-8")
    text = KNEE_TEXT.replace("file: trajectories/subject_B_synthetic.csv", "file: trajectories/long.csv")
    message = error_of(write(workdir, text))
    assert message.startswith(f"broken.yaml:{line_of(text, 'file: trajectories/long.csv')}: "), message
    assert (
        "trajectories.subject_B.file: " in message
        and "more than the 5,000,000 a trajectory may have" in message
    )


def test_a_misspelt_required_key_is_named_first(workdir: Path) -> None:
    """pydantic lists the missing field before the unknown key; the typo, the cause, comes first."""
    text = KNEE_TEXT.replace("periods:", "perods:", 1)
    assert text != KNEE_TEXT
    lines = error_of(write(workdir, text)).splitlines()
    assert re.search(r"\.perods: unknown key", lines[0]), lines
    assert re.search(r"\.periods: required field is missing", lines[1]), lines


def test_a_configuration_key_beyond_any_archive_integer_is_refused_at_its_line(workdir: Path) -> None:
    """A key of 10^23 passed validation and crashed the run at its first trial (no HDF5 integer holds it)."""
    text = KNEE_TEXT.replace("{key: 10, run: 1,", "{key: 99999999999999999999999, run: 1,", 1)
    assert text != KNEE_TEXT
    message = error_of(write(workdir, text))
    assert message.startswith(f"broken.yaml:{line_of(text, 'key: 99999999999999999999999')}:"), message
    assert "key: input should be less than or equal to 999999" in message, message


def test_a_speed_beyond_any_campaigns_magnitude_is_refused_at_its_line(workdir: Path) -> None:
    """A speed of 1e300 deg/s passed the schema and overflowed in the plan's acceleration check (a
    traceback); every number is bounded, so the later arithmetic stays finite."""
    text = KNEE_TEXT.replace("Full: {speed_deg_s: 50.0}", "Full: {speed_deg_s: 1e300}", 1)
    assert text != KNEE_TEXT
    message = error_of(write(workdir, text))
    assert message.startswith(
        f"broken.yaml:{line_of(text, 'speed_deg_s: 1e300')}: factors.speed.Full.speed_deg_s: "
    )
    assert "1e+300 is beyond the 1e+09" in message, message


def test_a_filter_cutoff_the_analysis_cannot_use_is_refused_before_anything_is_recorded(
    workdir: Path,
) -> None:
    """A cutoff of 1e-12 of Nyquist passed validation; the zero-phase filter then raised LinAlgError
    (a singular initial-condition system) after every trial had been recorded."""
    text = KNEE_TEXT.replace("cutoff: 0.10}", "cutoff: 1e-12}", 1)
    assert text != KNEE_TEXT
    message = error_of(write(workdir, text))
    assert message.startswith(f"broken.yaml:{line_of(text, 'cutoff: 1e-12')}: processing.filter.cutoff: ")
    assert "greater than or equal to 0.0001" in message, message


def test_the_smallest_cutoff_allowed_filters_without_error() -> None:
    """The floor is where the filter still works: a record filtered at the lowest cutoff stays finite."""
    import numpy as np
    from scipy.signal import butter, sosfiltfilt

    from protocol_runner.protocol.schema import FilterSpec

    floor = FilterSpec.model_fields["cutoff"].metadata[0].ge
    noise = np.random.default_rng(1).normal(size=20_000)
    filtered = sosfiltfilt(butter(20, floor, output="sos"), noise)
    assert np.all(np.isfinite(filtered))


def test_a_calibration_step_that_does_not_move_is_refused(workdir: Path) -> None:
    """`step_deg: 0` "passed" with a time constant of 0.279 s fitted to noise; a step below the declared
    minimum (calibration_check.min_step_deg, 5 deg unless declared) is refused at its line."""
    text = KNEE_TEXT.replace("  step_deg: 45", "  step_deg: 0", 1)
    assert text != KNEE_TEXT
    message = error_of(write(workdir, text))
    assert message.startswith(f"broken.yaml:{line_of(text, '  step_deg: 0')}: calibration_step.step_deg: ")
    assert "smaller than calibration_check.min_step_deg = 5 deg" in message, message
    declared = text.replace("calibration_check:", "calibration_check:\n  min_step_deg: 0.0001", 1)
    assert "calibration_check:\n  min_step_deg" in declared
    tiny = declared.replace("  step_deg: 0", "  step_deg: 0.00001", 1)
    assert "min_step_deg = 0.0001 deg" in error_of(write(workdir, tiny))


def test_a_generator_of_millions_of_configurations_is_refused_before_it_is_expanded(workdir: Path) -> None:
    """A full factorial of 600,000 configurations ran --validate past 120 s at 3.8 GB, and 6 million gave
    a traceback. The count is worked out from the level lists, and the cap named, before any is made."""
    from protocol_runner.protocol.generators import MAX_CONFIGURATIONS

    text = (workdir / "elbow_example.yaml").read_text(encoding="utf-8")
    levels = "".join(
        f"  f{i}:\n" + "".join(f'    l{j}: {{setup: "level {j}"}}\n' for j in range(60)) for i in range(4)
    )
    big = text.replace("factors:\n", "factors:\n" + levels, 1).replace(
        "factors: {damping: all, torsion: all}",
        "factors: {damping: all, torsion: all, f0: all, f1: all, f2: all, f3: all}",
    )
    assert big.count("f3: all") == 1
    message = error_of(write(workdir, big))
    assert message.startswith(f"broken.yaml:{line_of(big, 'full_factorial:')}: sets[0].full_factorial: "), (
        message
    )
    assert "makes 77,760,000 configurations" in message and f"{MAX_CONFIGURATIONS:,}" in message, message
