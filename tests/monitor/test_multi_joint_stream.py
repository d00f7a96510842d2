"""A two-joint dry run watched through `/events`: the monitor serves the samples of BOTH driven joints, each
joint's from its own input channels and inside its own range, on the same scan rows."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from protocol_runner.commands import run
from protocol_runner.monitor.service import Monitor

from .test_stream import _watch

REPO = Path(__file__).resolve().parents[2]
JOINTS = ["knee_flexion", "ankle_flexion"]
TRIAL = "trial:k02:on:1"  # the fast gait-like motion (trajectories/leg_gait_fast_synthetic.csv)


def two_joint_protocol(folder: Path) -> Path:
    """protocols/leg_phase2.yaml without the hip: the knee (inputs 8 and 20) and the ankle (inputs 10 and
    22) driven together, each with its own brace."""
    shutil.copytree(REPO / "protocols", folder)
    text = (folder / "leg_phase2.yaml").read_text(encoding="utf-8")
    two = (
        text.replace(
            "joints: [hip_flexion, knee_flexion, ankle_flexion]", "joints: [knee_flexion, ankle_flexion]"
        )
        .replace("    hip_flexion:\n      safety: {max_rate_deg_s: 90, park_angle_deg: 20}\n", "")
        .replace("  hip_flexion: {from_deg: 10, step_deg: 30, ramp_s: 0.8, hold_s: 4.0, settle_s: 1.0}\n", "")
    )
    assert two.count("hip_flexion") == 0
    path = folder / "leg_two_joints.yaml"
    path.write_text(two, encoding="utf-8")
    return path


def test_a_two_joint_dry_run_serves_samples_of_both_joints(tmp_path: Path) -> None:
    protocol = two_joint_protocol(tmp_path / "protocols")
    session = tmp_path / "session"

    def action(live: Monitor) -> int:
        return run(
            str(protocol),
            dry_run=True,
            session=session,
            seed=11,
            yes=True,
            only=[2],
            realtime=False,
            quiet=True,
            monitor=live,
        )

    code, _, messages, status, _ = _watch(session, action)
    assert code == 0
    hello = next(m for m in messages if m["type"] == "session")
    assert hello["joints"] == JOINTS
    runs: dict[str, list[list[float]]] = {joint: [] for joint in JOINTS}
    for m in messages:
        if m["type"] == "samples" and m["where"] == TRIAL:
            runs[m["joint"]].extend(m["points"])
    knee, ankle = (np.array(runs[j], dtype=np.float64) for j in JOINTS)
    # both joints' samples of the trial, at 20 Hz on the same scan rows (one scan reads every joint)
    assert knee.shape[0] >= 0.9 * 20.0 * 20 and ankle.shape[0] == knee.shape[0]
    assert np.array_equal(knee[:, 0], ankle[:, 0])
    # each from its own channels: the knee swings through its gait-like range inside the brace's R3 stops
    # [0, 130] deg, the ankle through its own (its brace's stops at -38 and 24 deg): different motions
    assert 55.0 < knee[:, 2].max() < 75.0 and knee[:, 2].min() > 0.0
    assert ankle[:, 2].min() > -38.0 and ankle[:, 2].max() < 24.0
    assert ankle[:, 2].max() - ankle[:, 2].min() > 10.0
    assert np.max(np.abs(knee[:, 2] - ankle[:, 2])) > 30.0
    # the first joint's command is shown with it, and the knee follows it (a 0.2 s first-order lag); the
    # ankle's, when the loop shows the monitor every joint's commands, is the ankle's own
    assert np.median(np.abs(knee[:, 1] - knee[:, 2])) < 10.0
    if not np.isnan(ankle[:, 1]).all():
        assert np.median(np.abs(ankle[:, 1] - ankle[:, 2])) < 10.0
    assert status["session"]["joints"] == JOINTS
