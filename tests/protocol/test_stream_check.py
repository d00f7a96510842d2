"""The plan-time check of every motion's complete commanded stream.

knee_phase1's motions pass it; what the old runner sent (a parking ramp to the first sample, the
trajectory, a parking ramp from the last) breaks the acceleration limit at every sinusoid start; protocols
whose streams cannot be sent within the envelope are refused before the run (exit 2), naming the
configuration and its line."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.safety import SafetyViolation, check_trajectory, parking_ramp_deg
from protocol_runner.hardware.stream import build_stream, check_stream
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import CalibrationCheckStep, TrialStep
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.session.rigs import joint_config

REPO = Path(__file__).resolve().parents[2]
KNEE = REPO / "protocols" / "knee_phase1.yaml"


@pytest.fixture()
def workdir(tmp_path: Path) -> Path:
    shutil.copytree(REPO / "protocols", tmp_path / "protocols")
    return tmp_path / "protocols"


def _motions() -> list[tuple[str, np.ndarray]]:
    loaded = load_protocol(KNEE)
    rate = loaded.protocol.rig.output.rate_hz
    seen: dict[str, tuple[str, np.ndarray]] = {}
    for step in expand(loaded).steps:
        if isinstance(step, CalibrationCheckStep) or (isinstance(step, TrialStep) and step.brace == "on"):
            key = repr(step.trajectory.to_json())
            if key not in seen:
                seen[key] = (step.id, sample_trajectory(step.trajectory, rate, loaded.base_dir))
    return list(seen.values())


def test_every_knee_phase1_motion_passes_the_full_stream_check_and_the_old_one_did_not() -> None:
    joint = joint_config(load_protocol(KNEE))
    limits, rate = joint.limits, joint.output_rate_hz
    motions = _motions()
    assert {m[0].split(":")[0] for m in motions} == {"cal", "trial"} and len(motions) >= 8
    old_worst: dict[str, float] = {}
    for step_id, cmd in motions:
        stream = build_stream(cmd, limits, rate)
        check_stream(
            stream, limits, where=step_id, command_table=joint.command_table, volts_range_deg=joint.range_deg
        )
        # what the old runner sent: approach = a parking ramp from the park angle to the first sample,
        # then the trajectory from rest, then a parking ramp from the last sample
        approach = parking_ramp_deg(
            limits.park_angle_deg, replace(limits, park_angle_deg=float(cmd[0])), rate
        )
        old = np.concatenate([approach, cmd, parking_ramp_deg(float(cmd[-1]), limits, rate)])
        try:
            check_trajectory(old, rate, limits, where=step_id)
        except SafetyViolation as exc:
            assert exc.limit == "angular acceleration"
            old_worst[step_id] = abs(exc.value)
    # every sinusoid trial (50 deg/s at its start) broke the 2,000 deg/s² limit by 2.5x
    full_speed = [v for k, v in old_worst.items() if v > 4900]
    assert len(full_speed) >= 4 and max(old_worst.values()) == pytest.approx(5000.0, rel=1e-3)


def _edit(workdir: Path, old: str, new: str) -> Path:
    path = workdir / "edited.yaml"
    text = KNEE.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_a_human_file_over_the_acceleration_limit_is_refused_with_its_configuration(workdir: Path) -> None:
    # a file that reverses from +50 to -50 deg/s within 10 ms: 10,000 deg/s², 5x the limit
    t = np.arange(0.0, 2.0, 0.01)
    angle = 40.0 + 50.0 * np.minimum(t, 2.0 - t)
    rows = "\n".join(f"{a:.3f},{b:.4f}" for a, b in zip(t, angle, strict=True))
    (workdir / "trajectories" / "corner.csv").write_text(
        f"# synthetic corner\ntime_s,angle_deg\n{rows}\n", encoding="utf-8"
    )
    path = _edit(workdir, "subject_B_synthetic.csv", "corner.csv")
    with pytest.raises(InvalidInput) as info:
        load_protocol(path, display_name="edited.yaml")
    message = info.value.message
    assert "trajectory 'subject_B' (file trajectories/corner.csv)" in message
    assert "angular acceleration" in message and "(configuration 24 in set 'emu_comparison')" in message
    assert message.startswith("edited.yaml:") and "trajectories.subject_B.file" in message
    assert main(["--validate", str(path)]) == 2


def test_a_calibration_step_over_the_acceleration_limit_is_refused(workdir: Path) -> None:
    """The raised-cosine 45 deg step over 0.6 s peaks at 617 deg/s² (616 sampled): a rig allowing 500 refuses it."""
    path = _edit(workdir, "max_accel_deg_s2: 2000", "max_accel_deg_s2: 500")
    with pytest.raises(
        InvalidInput, match=r"calibration_step\.ramp_s: .*peak acceleration .*616\.9 deg/s² is over"
    ):
        load_protocol(path, display_name="edited.yaml")
