"""The output loop's tap: 20 Hz points that are exactly the recording's values, at no cost to the data."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.interfaces import ScanBlock
from protocol_runner.hardware.joint import TrialRecording
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.monitor.live import SampleTap, phase_of

from ..knee_rig import knee_joint_config

# A gentle, non-identity angle table, so the tap's conversion is the recording's, not a plain Eq 2.
ANGLE_TABLE = CalibrationTable(
    np.array([0.0, 60.0, 130.0]), np.array([0.0, 62.0, 130.0]), "output_deg", "real_deg"
)


def knee() -> Any:
    return knee_joint_config(max_rate_deg_s=200.0, max_accel_deg_s2=2000.0, angle_table=ANGLE_TABLE)


def trial(tap: SampleTap | None, seed: int = 11) -> TrialRecording:
    sim = SimulatedRig([knee()], seed=seed)
    rig = sim.make_rig()
    rig.tap = tap
    sim.begin_step("trial:x")
    # from the park angle (20 deg) and back, twice: 20-90 deg, at most 73 deg/s and 154 deg/s^2
    cmd = 20.0 + 35.0 * (1 - np.cos(2 * np.pi * np.arange(0.0, 6.0, 0.01) / 3.0))
    if tap is not None:
        tap.step = "trial:x"
    return rig.run_trajectory([cmd], where="trial:x")[0]


def test_points_are_20_hz_and_equal_to_what_is_recorded() -> None:
    sent: list[dict[str, Any]] = []
    tap = SampleTap((knee(),), sent.append)
    rec = trial(tap)
    assert sent and all(m["step"] == "trial:x" and m["phase"] == "run" for m in sent)
    points = np.array([p for m in sent for p in m["points"]])
    t_rel = points[:, 0] - rec.t0_s
    assert np.allclose(np.diff(t_rel), 0.05, atol=1e-3)  # 20 Hz of scan time
    assert points.shape[0] >= 0.98 * rec.n_ticks / 100 * 20
    rows = np.searchsorted(rec.input_time_s, t_rel - 1e-4)
    assert np.allclose(points[:, 2], rec.angle_deg[rows], atol=1e-3)  # Eq 2 + the angle table
    assert np.allclose(points[:, 3], rec.torque_nm[rows], atol=1e-3)  # Eq 3
    ticks = np.clip((t_rel * 100).astype(int), 0, rec.n_ticks - 1)
    assert np.allclose(points[:, 1], rec.command_deg[ticks], atol=1e-3)


def test_the_tap_changes_nothing_recorded() -> None:
    plain = trial(None)
    watched = trial(SampleTap((knee(),), lambda m: None))
    for name in ("command_codes", "angle_codes", "torque_codes", "angle_deg", "torque_nm"):
        assert np.array_equal(getattr(plain, name), getattr(watched, name)), name


def test_a_failing_tap_switches_itself_off_and_the_loop_goes_on() -> None:
    def broken_sink(msg: dict[str, Any]) -> None:
        raise RuntimeError("the bus is gone")

    tap = SampleTap((knee(),), broken_sink)
    rec = trial(tap)
    assert rec.n_ticks == 600  # the whole trial ran
    assert not tap.enabled and "the bus is gone" in tap.error
    tap.scan(ScanBlock.empty(1))  # once off, it ignores everything


def test_a_block_of_the_wrong_shape_does_not_raise() -> None:
    tap = SampleTap((knee(),), lambda m: None)
    tap.start("x", np.zeros(10), 0.0)
    odd = ScanBlock(t_s=np.arange(5) / 1000, codes=np.zeros((5, 1), np.int32), volts=np.zeros((5, 1)))
    tap.scan(odd)
    assert not tap.enabled


@pytest.mark.parametrize(
    ("where", "phase"),
    [
        ("trial:k01:on:1", "run"),
        ("trial:k01:on:1 (approach)", "approach"),
        ("trial:k01:on:1 (park)", "park"),
        ("trial:k01:off:1 (scaling run 2)", "run"),
        ("trial:k01:off:1 (scaling run 2) (approach)", "approach"),
        ("park on stop", "park"),
    ],
)
def test_phase_of_a_run(where: str, phase: str) -> None:
    assert phase_of(where) == phase


def test_each_joint_is_read_from_its_own_channels_with_its_own_command() -> None:
    """Two joints whose scan order is not their command order: each joint's samples come from the scan
    columns of its own input channels, and its command from its own column of the commands."""
    knee_joint = knee()
    hip = replace(
        knee_joint, name="hip_flexion", output_channel=5, angle_input_channel=5, torque_input_channel=17
    )
    sent: list[dict[str, Any]] = []
    # the commands in joint order (knee, hip); the scan lists the hip's channels first
    tap = SampleTap((knee_joint, hip), sent.append, scan_channels=(5, 17, 8, 20))
    assert tap.names == ("knee", "hip_flexion")
    columns = np.array([1.0, -2.0, 3.0, 4.0])  # volts of channels 5, 17, 8, 20
    block = ScanBlock(
        t_s=np.arange(100) / 1000.0, codes=np.zeros((100, 4), np.int32), volts=np.tile(columns, (100, 1))
    )
    tap.start("trial:x", np.column_stack((np.full(20, 30.0), np.full(20, 50.0))), 0.0)
    tap.scan(block)
    by_joint = {m["joint"]: np.array(m["points"], dtype=np.float64) for m in sent}
    assert set(by_joint) == {"knee", "hip_flexion"} and len(sent) == 2
    knee_pts, hip_pts = by_joint["knee"], by_joint["hip_flexion"]
    assert np.array_equal(knee_pts[:, 0], hip_pts[:, 0])  # the same rows of the one scan
    assert np.allclose(
        knee_pts[:, 1:],
        [30.0, knee_joint.angle_from_volts(3.0), knee_joint.torque_from_volts(4.0)],
        atol=1e-3,
    )
    assert np.allclose(
        hip_pts[:, 1:], [50.0, hip.angle_from_volts(1.0), hip.torque_from_volts(-2.0)], atol=1e-3
    )

    # the first joint's commands alone: the other joint is shown without a commanded angle
    sent.clear()
    tap.start("trial:y", np.full(20, 30.0), 0.0)
    tap.scan(block)
    by_joint = {m["joint"]: np.array(m["points"], dtype=np.float64) for m in sent}
    assert np.all(by_joint["knee"][:, 1] == 30.0) and np.all(np.isnan(by_joint["hip_flexion"][:, 1]))

    # a block with the first two scan columns only (a loop that shows only some joints): only the hip's
    sent.clear()
    tap.start("trial:z", np.full(20, 30.0), 0.0)
    tap.scan(ScanBlock(t_s=block.t_s, codes=block.codes[:, :2], volts=block.volts[:, :2]))
    assert [m["joint"] for m in sent] == ["hip_flexion"] and tap.enabled
