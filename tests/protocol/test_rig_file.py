"""The shipped rig file (src/protocol_runner/rigs/rsst.yaml) against thesis Tables 1-3 and §2.3-2.4, and
rig-file mistakes named with the rig file's line and field."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.protocol.rig_file import find_rig, load_rig, resolve_rig
from protocol_runner.protocol.schema import RigOverrides
from protocol_runner.resources import packaged_rigs_dir
from tests.rsst_reference import RSST_JOINTS

RSST = packaged_rigs_dir() / "rsst.yaml"


def test_the_rig_is_found_by_name_inside_the_package(tmp_path: Path) -> None:
    assert find_rig("rsst", tmp_path) == RSST
    assert (
        RSST.is_relative_to(Path(__file__).resolve().parents[2] / "src" / "protocol_runner") or RSST.is_file()
    )
    with pytest.raises(InvalidInput, match="unknown rig 'nope'"):
        find_rig("nope", tmp_path)


def test_all_twelve_joints_follow_tables_1_to_3_and_the_channel_rule() -> None:
    rig = load_rig(RSST).rig
    assert len(rig.joints) == 12
    for name, joint in rig.joints.items():
        table = RSST_JOINTS[joint.number]
        assert joint.description == table.name and name == table.name.lower().replace(" ", "_")
        assert joint.range_deg == tuple(table.range_deg) and joint.torque_range_nm == tuple(
            table.torque_range_nm
        )
        n = joint.number
        assert (joint.output_channel, joint.angle_channel, joint.torque_channel) == (n - 1, n - 1, 12 + n - 1)
    assert rig.joint_defaults.time_constant_s == 0.2  # §2.4.2
    assert rig.boards["usb3105"].rate_hz == 100 and rig.boards["usb3105"].resolution_bits == 16  # §2.3
    assert rig.boards["dt9814"].channels == 24 and rig.boards["dt9814"].resolution_bits == 12


def test_the_knee_keeps_todays_simulator_values_and_every_key_is_a_simulator_field() -> None:
    loaded = load_rig(RSST)
    fields = {f.name for f in dataclasses.fields(SimulatorParams)}
    assert set(loaded.rig.joint_defaults.simulator) <= fields
    spec, problems = resolve_rig(loaded, "knee_flexion", RigOverrides())
    assert problems == [] and spec is not None
    sim = SimulatorParams(**dict(spec.simulator))
    assert (sim.gravity_torque_max_nm, sim.lag_time_constant_s, sim.robot_friction_nm) == (35.5, 0.17, 2.5)
    assert sim.robot_viscous_nm_per_deg_s == 0.03
    assert (spec.output.channel, spec.input.angle_channel, spec.input.torque_channel) == (8, 8, 20)


def _broken(tmp_path: Path, old: str, new: str, needle: str) -> str:
    """Edit the rig file; the error must start with the rig file's name and the line of `needle`."""
    text = RSST.read_text(encoding="utf-8")
    assert old in text
    edited = text.replace(old, new, 1)
    line = edited[: text.index(old) + new.index(needle)].count("\n") + 1
    path = tmp_path / "rig.yaml"
    path.write_text(edited, encoding="utf-8")
    with pytest.raises(InvalidInput) as info:
        load_rig(path)
    assert info.value.message.startswith(f"rig.yaml:{line}: "), info.value.message
    return info.value.message


def test_two_joints_on_one_channel_name_the_rig_file_line_and_field(tmp_path: Path) -> None:
    message = _broken(tmp_path, "    torque_channel: 22\n", "    torque_channel: 20\n", "torque")
    assert re.search(
        r"joints\.ankle_flexion\.torque_channel: input channel 20 is already used by knee_flexion", message
    )
    message = _broken(tmp_path, "    output_channel: 10\n", "    output_channel: 8\n", "output")
    assert "joints.ankle_flexion.output_channel: output channel 8 is already knee_flexion's" in message


def test_unknown_keys_and_bad_ranges_in_the_rig_file_are_located(tmp_path: Path) -> None:
    assert "joint_defaults.simulator.gravity_nm: unknown simulator parameter" in _broken(
        tmp_path, "    gravity_torque_max_nm: 0.0 ", "    gravity_nm: 0.0 ", "gravity"
    )
    assert "joints.knee_flexion.range_deg: range must be [low, high]" in _broken(
        tmp_path,
        "    range_deg: [0, 130]\n    torque_range_nm: [-84.8",
        "    range_deg: [130, 0]\n    torque_range_nm: [-84.8",
        "range",
    )
    assert "joints.knee_flexion.colour: unknown key" in _broken(
        tmp_path, "    number: 9\n", "    number: 9\n    colour: red\n", "colour"
    )


def test_a_boolean_for_a_rate_in_the_rig_file_is_refused_at_its_line(tmp_path: Path) -> None:
    message = _broken(tmp_path, "    rate_hz: 100 ", "    rate_hz: yes ", "rate_hz")
    assert "boards.usb3105.rate_hz: expected a number, got True (YAML reads yes, no, on, off" in message


@pytest.mark.parametrize(
    ("old", "new", "needle", "expected"),
    [
        (
            "    plant_step_s: 0.0005 ",
            "    plant_step_s: 1.0e-12 ",
            "plant_step_s",
            "joint_defaults.simulator.plant_step_s: must lie in [1e-05, 0.01], got 1e-12",
        ),
        (
            "    lag_time_constant_s: 0.17 ",
            "    lag_time_constant_s: 0 ",
            "lag_time_constant_s",
            "joint_defaults.simulator.lag_time_constant_s: must lie in [0.001, 10], got 0",
        ),
        (
            "    relief_speed_deg_s_per_nm: 5.0 ",
            "    relief_speed_deg_s_per_nm: -5.0 ",
            "relief_speed",
            "joint_defaults.simulator.relief_speed_deg_s_per_nm: must be >= 0, got -5.0",
        ),
        (
            "    rate_hz: 100 ",
            "    rate_hz: 1.0e-9 ",
            "rate_hz",
            "boards.usb3105.rate_hz: an output board's rate must lie in [1, 1000] Hz, got 1e-09",
        ),
        (
            "    rate_hz: 100 ",
            "    rate_hz: 50000 ",
            "rate_hz",
            "boards.usb3105.rate_hz: an output board's rate must lie in [1, 1000] Hz, got 50000",
        ),
        (
            "    rate_hz: 1000                    # the scan rate used",
            "    rate_hz: 0.001                   # the scan rate used",
            "rate_hz",
            "boards.dt9814.rate_hz: an input board's rate must lie in [10, 25000] Hz, got 0.001",
        ),
        (
            "    rate_hz: 1000                    # the scan rate used",
            "    rate_hz: 50000                   # two channels: 100,000 samples/s",
            "rate_hz",
            "boards.dt9814.rate_hz: an input board's rate must lie in [10, 25000] Hz, got 50000",
        ),
        (
            "    torque_range_nm: [-84.8, 84.8]",
            "    torque_range_nm: [5.0, 84.8]",
            "torque_range_nm",
            "joints.knee_flexion.torque_range_nm: the load cell's range must include 0 N·m",
        ),
    ],
    ids=[
        "plant step",
        "lag",
        "negative",
        "output rate tiny",
        "output rate high",
        "input rate",
        "input rate over the two channels' limit",
        "torque range",
    ],
)
def test_a_rig_value_that_would_make_the_run_unbounded_or_crash_is_refused_at_its_line(
    tmp_path: Path, old: str, new: str, needle: str, expected: str
) -> None:
    """Each once passed `--validate` and then ran for ever, asked for terabytes, or crashed the dry run
    (or, for a fast output board, `--validate` itself) with a traceback."""
    assert expected in _broken(tmp_path, old, new, needle)
