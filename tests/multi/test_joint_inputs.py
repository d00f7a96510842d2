"""The input side of a campaign of several joints, refused before anything moves (exit 2, file, line and
field): a device declared per joint, each joint driven once on channels of its own, per-joint trajectories
covering exactly the driven joints, and one tick's output reports fitting in the tick (the USB-3105 sends
one report per channel plus one AOUT_SYNC)."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.cli import main
from protocol_runner.hardware.motion import run_motion
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import TrialStep, expand
from protocol_runner.protocol.validate import output_budget
from protocol_runner.session.rigs import joint_config

REPO = Path(__file__).resolve().parents[2]
LEG_TEXT = (REPO / "protocols" / "leg_phase2.yaml").read_text(encoding="utf-8")
SUIT_TEXT = (REPO / "protocols" / "suit_phase4.yaml").read_text(encoding="utf-8")
RIG_TEXT = (REPO / "src" / "protocol_runner" / "rigs" / "rsst.yaml").read_text(encoding="utf-8")
SUIT_RATE = "  output_rate_hz: 50 "


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    shutil.copytree(REPO / "protocols", tmp_path / "protocols")
    return tmp_path / "protocols"


def _line(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), start=1) if needle in ln)


def _refused(workdir: Path, text: str, capsys: pytest.CaptureFixture[str], name: str = "bad.yaml") -> str:
    (workdir / name).write_text(text, encoding="utf-8")
    assert main(["--validate", str(workdir / name)]) == 2
    return capsys.readouterr().err


def _valid(workdir: Path, text: str, capsys: pytest.CaptureFixture[str], name: str = "ok.yaml") -> None:
    (workdir / name).write_text(text, encoding="utf-8")
    assert main(["--validate", str(workdir / name)]) == 0, capsys.readouterr().err


# ------------------------------------------------------------------------------------ the device


def _flat_leg_device() -> str:
    """leg_phase2 with the knee's and the ankle's elements in one flat list (the ankle's hinge renamed)."""
    knee_head = "  joints:\n    knee_flexion:\n      elements:\n"
    ankle_head = "    ankle_flexion:\n      elements:\n"
    assert knee_head in LEG_TEXT and ankle_head in LEG_TEXT
    text = LEG_TEXT.replace(knee_head, "  elements:\n").replace(ankle_head, "")
    return text.replace(
        "{name: hinge, type: coulomb_brake, torque_nm: 0.5",
        "{name: ankle_hinge, type: coulomb_brake, torque_nm: 0.5",
    )


def test_a_flat_element_list_of_several_joints_is_refused_naming_the_fix(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a flat list would put the knee's springs and the ankle's bungee on the hip, the knee and the ankle
    text = _flat_leg_device()
    err = _refused(workdir, text, capsys)
    assert f"bad.yaml:{_line(text, '  elements:')}: device.elements: this campaign drives 3 joints" in err
    assert "device.joints.<joint>.elements" in err


def test_elements_stay_on_the_joint_that_carries_them() -> None:
    steps = expand(load_protocol(REPO / "protocols" / "leg_phase2.yaml")).steps
    st = next(s for s in steps if isinstance(s, TrialStep) and s.brace == "on").settings
    assert st.device_of("hip_flexion") == ()
    assert "springs" in [e.name for e in st.device_of("knee_flexion")]
    assert "bungee" not in [e.name for e in st.device_of("knee_flexion")]
    assert [e.name for e in st.device_of("ankle_flexion")] == ["stops", "bungee", "hinge"]


def test_a_device_of_an_undriven_joint_is_one_line_at_its_entry(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = LEG_TEXT.replace("    ankle_flexion:\n      elements:", "    elbow_flexion:\n      elements:")
    err = _refused(workdir, text, capsys)
    line = _line(text, "    elbow_flexion:")
    expected = (
        f"bad.yaml:{line}: device.joints.elbow_flexion: 'elbow_flexion' is not one of the driven joints"
    )
    assert expected in err and err.count("elbow_flexion' is not one") == 1


# ------------------------------------------------------------------------------------ joints, channels


def test_a_joint_named_twice_is_refused_at_its_entry(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = LEG_TEXT.replace(
        "joints: [hip_flexion, knee_flexion, ankle_flexion]",
        "joints: [hip_flexion, knee_flexion, knee_flexion]",
    )
    err = _refused(workdir, text, capsys)
    assert f"bad.yaml:{_line(text, 'joints: [hip_flexion')}: joints[2]: 'knee_flexion' is listed twice" in err


@pytest.mark.parametrize(
    ("field", "edit", "message"),
    [
        (
            "output_channel",
            ("    output_channel: 10\n", "    output_channel: 8\n"),
            "output channel 8 is already",
        ),
        (
            "angle_channel",
            ("    angle_channel: 10\n", "    angle_channel: 8\n"),
            "input channel 8 is already used by",
        ),
        (
            "torque_channel",
            ("    torque_channel: 22\n", "    torque_channel: 20\n"),
            "input channel 20 is already used by",
        ),
    ],
)
def test_two_joints_on_one_channel_of_the_rig_file_name_its_line_and_field(
    workdir: Path, capsys: pytest.CaptureFixture[str], field: str, edit: tuple[str, str], message: str
) -> None:
    rig = RIG_TEXT.replace(*edit, 1)  # ankle_flexion (joint 11) onto the knee's channel
    (workdir / "bad_rig.yaml").write_text(rig, encoding="utf-8")
    err = _refused(workdir, LEG_TEXT.replace("rig: rsst", "rig: bad_rig.yaml"), capsys)
    lines = [i for i, ln in enumerate(rig.splitlines(), start=1) if ln == edit[1].rstrip("\n")]
    line = lines[-1]  # the second joint to claim the channel: ankle_flexion
    assert f"bad_rig.yaml:{line}: joints.ankle_flexion.{field}: {message} knee_flexion" in err


def test_rig_overrides_cannot_move_a_joint_to_another_channel(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = LEG_TEXT.replace(
        "      safety: {max_rate_deg_s: 90, park_angle_deg: 0}",
        "      output_channel: 8\n      safety: {max_rate_deg_s: 90, park_angle_deg: 0}",
    )
    err = _refused(workdir, text, capsys)
    assert (
        f"bad.yaml:{_line(text, 'output_channel: 8')}: rig_overrides.joints.ankle_flexion.output_channel"
        in err
    )


# ------------------------------------------------------------------------------------ per-joint trajectories

PER_JOINT = (
    "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
    "      hip_flexion: {kind: sinusoid, range_deg: [10, 40], speed_deg_s: 15, periods: 2}\n"
    "      knee_flexion: {kind: sinusoid, range_deg: [20, 90], speed_deg_s: 35, periods: 2}\n"
    "      ankle_flexion: {kind: sinusoid, range_deg: [-10, 10], speed_deg_s: 10, periods: 2}"
)
SIT = "  sit_to_stand: {kind: file, file: trajectories/leg_sit_to_stand_synthetic.csv}"


def test_a_per_joint_trajectory_missing_a_joint_is_refused_at_its_joints(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = LEG_TEXT.replace(SIT, "\n".join(PER_JOINT.splitlines()[:-1]))
    err = _refused(workdir, text, capsys)
    line = _line(text, "kind: per_joint") + 1  # its `joints:`
    assert (
        f"bad.yaml:{line}: trajectories.sit_to_stand.joints: no entry for driven joint(s) ankle_flexion"
        in err
    )


def test_a_trajectory_file_without_a_driven_joints_column_is_refused_at_its_column_row(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A `file` trajectory of several joints needs one angle column per driven joint: the file's column row
    is named, and the configuration that uses it, before anything moves."""
    csv = workdir / "trajectories" / "leg_gait_slow_synthetic.csv"
    lines = csv.read_text(encoding="utf-8").splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.startswith("time_s,"))
    assert lines[header] == "time_s,hip_flexion,knee_flexion,ankle_flexion"
    kept = [ln if ln.startswith("#") else ",".join(ln.split(",")[:3]) for ln in lines]  # no ankle column
    csv.write_text("\n".join(kept) + "\n", encoding="utf-8")
    err = _refused(workdir, LEG_TEXT, capsys)
    assert (
        f"trajectories/leg_gait_slow_synthetic.csv:{header + 1}: the column row must name `time_s` and "
        "`ankle_flexion`" in err
    )
    assert "joint ankle_flexion: trajectory 'gait_slow'" in err and "Traceback" not in err


def test_a_per_joint_trajectory_naming_an_undriven_joint_is_refused_at_that_entry(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    extra = "\n      elbow_flexion: {kind: sinusoid, range_deg: [20, 90], speed_deg_s: 35, periods: 2}"
    text = LEG_TEXT.replace(SIT, PER_JOINT + extra)
    err = _refused(workdir, text, capsys)
    line = _line(text, "      elbow_flexion:")
    assert (
        f"bad.yaml:{line}: trajectories.sit_to_stand.joints.elbow_flexion: 'elbow_flexion' is not one of the driven joints"
        in err
    )


# ------------------------------------------------------------------------------------ the output budget


def test_the_budget_arithmetic() -> None:
    # 12 joints: 12 AOUT + 1 AOUT_SYNC at 1 ms each = 13 ms; a 100 Hz tick is 10 ms; 1 / 13 ms = 76.9 Hz
    needed_s, tick_s, largest_hz = output_budget(12, 0.001, 100.0)
    assert needed_s == pytest.approx(0.013) and tick_s == pytest.approx(0.010) and largest_hz == 76
    assert output_budget(12, 0.001, 50.0)[0] < output_budget(12, 0.001, 50.0)[1]  # 13 ms < 20 ms
    assert output_budget(3, 0.001, 100.0)[2] == 250  # the leg: 4 ms per tick


def test_twelve_joints_at_100_hz_are_refused_with_the_numbers(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = "\n".join(ln for ln in SUIT_TEXT.splitlines() if not ln.startswith(SUIT_RATE)) + "\n"
    err = _refused(workdir, text, capsys)
    assert (
        f"bad.yaml:{_line(text, 'joints: [shoulder_flexion')}: joints: 12 joints need 13 output reports"
        in err
    )
    assert "= 13 ms, more than one 10 ms tick at 100 Hz" in err
    assert "the largest output rate that fits is 76 Hz" in err


def test_a_lowered_rate_that_still_does_not_fit_is_refused_at_the_override(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = SUIT_TEXT.replace(SUIT_RATE, "  output_rate_hz: 80 ")
    err = _refused(workdir, text, capsys)
    assert f"bad.yaml:{_line(text, 'output_rate_hz: 80')}: rig_overrides.output_rate_hz: 12 joints" in err
    assert "more than one 12.5 ms tick at 80 Hz" in err


def test_the_output_rate_may_only_be_lowered(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = SUIT_TEXT.replace(SUIT_RATE, "  output_rate_hz: 200 ")
    err = _refused(workdir, text, capsys)
    line = _line(text, "output_rate_hz: 200")
    assert f"bad.yaml:{line}: rig_overrides.output_rate_hz: 200 Hz is above the output board usb3105's" in err
    assert err.count("200 Hz is above") == 1  # once, not once per joint


def test_the_rig_files_output_board_states_its_report_time(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = "\n".join(ln for ln in RIG_TEXT.splitlines() if not ln.lstrip().startswith("report_time_s:")) + "\n"
    (workdir / "no_report.yaml").write_text(rig, encoding="utf-8")
    err = _refused(workdir, LEG_TEXT.replace("rig: rsst", "rig: no_report.yaml"), capsys)
    assert (
        f"no_report.yaml:{_line(rig, '  usb3105:')}: boards.usb3105: an output board states report_time_s"
        in err
    )


def test_the_lowered_rate_is_every_joints_tick(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _valid(workdir, SUIT_TEXT, capsys, "suit.yaml")
    loaded = load_protocol(workdir / "suit.yaml")
    assert {r.output.rate_hz for r in loaded.protocol.rigs} == {50.0}
    assert {joint_config(loaded, r).output_rate_hz for r in loaded.protocol.rigs} == {50.0}


def _sinusoids(knee_speed_deg_s: float) -> str:
    """The three joints' sinusoids sharing one period: each speed in proportion to its range."""
    ratio = knee_speed_deg_s / 64.0
    return (
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        f"      hip_flexion: {{kind: sinusoid, range_deg: [10, 40], speed_deg_s: {30 * ratio}, periods: 3}}\n"
        f"      knee_flexion: {{kind: sinusoid, range_deg: [20, 84], speed_deg_s: {64 * ratio}, periods: 3}}\n"
        f"      ankle_flexion: {{kind: sinusoid, range_deg: [-10, 10], speed_deg_s: {20 * ratio}, periods: 3}}"
    )


def test_the_rate_and_acceleration_limits_use_the_real_tick(
    workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the knee peaks at 95 deg/s under its 100 deg/s limit: at 50 Hz a sample moves up to 1.9 deg, which read
    # as a 100 Hz tick would be 190 deg/s; the protocol is valid only if the checks divide by the 50 Hz tick
    lowered = LEG_TEXT.replace("  input_board: usb1608fs", "  output_rate_hz: 50\n  input_board: usb1608fs")
    _valid(workdir, lowered.replace(SIT, _sinusoids(95.0)), capsys)
    # and the limit still holds at 50 Hz: 110 deg/s is above the knee's 100
    err = _refused(workdir, lowered.replace(SIT, _sinusoids(110.0)), capsys)
    assert "joint knee_flexion" in err and "max_rate_deg_s" in err
    assert "joint hip_flexion" not in err and "joint ankle_flexion" not in err


def test_the_paced_loop_writes_one_tick_per_lowered_period() -> None:
    loaded = load_protocol(REPO / "protocols" / "leg_phase2.yaml")
    joints = [dataclasses.replace(joint_config(loaded, r), output_rate_hz=50.0) for r in loaded.protocol.rigs]
    params = [SimulatorParams(**dict(r.simulator)) for r in loaded.protocol.rigs]
    sim = SimulatedRig(joints, params=params, seed=1)
    hold = [np.full(100, j.limits.park_angle_deg) for j in joints]  # 2 s at 50 Hz
    recs = run_motion(sim.make_rig(), hold, where="trial")
    assert {rec.output_rate_hz for rec in recs} == {50.0}
    written_s, channel, _code = sim.ao.records()  # the simulated board's writes, on its clock
    for j in joints:
        ticks_s = written_s[channel == j.output_channel][1:]  # after the channel's first write at t0
        assert np.diff(ticks_s) == pytest.approx(0.02, abs=1e-6)
