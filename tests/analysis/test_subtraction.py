"""Robot-torque subtraction at equal angles vs at equal times (thesis §3.3, §5.6)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.filters import lowpass
from protocol_runner.analysis.subtraction import (
    robot_torque_at_equal_angle,
    subtract_equal_angle,
    subtract_equal_time,
)
from protocol_runner.analysis.validation import AnalysisError

from .synth import brace_pair


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def _away_from_turns(angle: np.ndarray, margin_deg: float = 1.5) -> np.ndarray:
    """Samples not within margin of the trial's extreme angles (where friction switches branch)."""
    return (angle > angle.min() + margin_deg) & (angle < angle.max() - margin_deg)


def test_ranges_differ_as_on_the_rig() -> None:
    d = brace_pair()
    assert d.angle_on_deg.max() - d.angle_on_deg.min() < 0.7 * (d.angle_off_deg.max() - d.angle_off_deg.min())


def test_equal_angle_recovers_the_brace_loop_where_equal_time_does_not() -> None:
    d = brace_pair()
    by_angle = subtract_equal_angle(d.angle_on_deg, d.torque_on_nm, d.angle_off_deg, d.torque_off_nm)
    by_time = subtract_equal_time(d.time_s, d.torque_on_nm, d.time_s, d.torque_off_nm)
    keep = _away_from_turns(d.angle_on_deg)
    assert _rmse(by_angle[keep], d.brace_true_nm[keep]) < 0.15
    assert _rmse(by_angle, d.brace_true_nm) < 1.0  # including the friction switch at the turning points
    # equal time compares the robot at different angles: errors of the size of the brace's friction
    assert _rmse(by_time[keep], d.brace_true_nm[keep]) > 2.0
    assert _rmse(by_time[keep], d.brace_true_nm[keep]) > 20 * _rmse(by_angle[keep], d.brace_true_nm[keep])


def test_equal_angle_on_noisy_filtered_data() -> None:
    d = brace_pair(noise=True, seed=7)
    angle_on = lowpass(d.angle_on_deg, cutoff=0.02)
    torque_on = lowpass(d.torque_on_nm, cutoff=0.02)
    angle_off = lowpass(d.angle_off_deg, cutoff=0.02)
    torque_off = lowpass(d.torque_off_nm, cutoff=0.02)
    brace = subtract_equal_angle(angle_on, torque_on, angle_off, torque_off)
    keep = _away_from_turns(angle_on, 3.0)
    keep[:500] = keep[-500:] = False  # filter edges
    assert _rmse(brace[keep], d.brace_true_nm[keep]) < 0.3


def test_identical_histories_make_both_methods_agree() -> None:
    d = brace_pair()
    torque_off = d.torque_on_nm - d.brace_true_nm  # the robot alone, on the brace-on angle history
    by_angle = subtract_equal_angle(d.angle_on_deg, d.torque_on_nm, d.angle_on_deg, torque_off)
    by_time = subtract_equal_time(d.time_s, d.torque_on_nm, d.time_s, torque_off)
    np.testing.assert_allclose(by_time, d.brace_true_nm, atol=1e-12)
    keep = _away_from_turns(d.angle_on_deg)
    assert _rmse(by_angle[keep], by_time[keep]) < 0.15


def test_brace_on_angles_beyond_the_brace_off_range() -> None:
    d = brace_pair()
    # use only the middle of the brace-off range: 40-90 deg
    mask = (d.angle_off_deg > 40.0) & (d.angle_off_deg < 90.0)
    robot, covered = robot_torque_at_equal_angle(
        d.angle_on_deg, d.angle_off_deg[mask], d.torque_off_nm[mask], outside="nan"
    )
    inside = (d.angle_on_deg > 41.0) & (d.angle_on_deg < 89.0)
    assert np.all(covered[inside])
    assert not np.any(covered[(d.angle_on_deg < 39.0) | (d.angle_on_deg > 91.0)])
    assert np.all(np.isnan(robot[~covered]))
    clipped = subtract_equal_angle(
        d.angle_on_deg, d.torque_on_nm, d.angle_off_deg[mask], d.torque_off_nm[mask], outside="clip"
    )
    assert np.all(np.isfinite(clipped))


def test_equal_time_uses_time_since_each_trial_start() -> None:
    t_on = np.array([5.0, 5.1, 5.2])
    t_off = np.array([2.0, 2.05, 2.1, 2.15, 2.2])
    q_off = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    out = subtract_equal_time(t_on, np.full(3, 10.0), t_off, q_off)
    np.testing.assert_allclose(out, [10.0, 8.0, 6.0])


def test_mismatched_lengths_are_rejected() -> None:
    with pytest.raises(AnalysisError, match="same number of samples"):
        subtract_equal_angle(np.zeros(5), np.zeros(4), np.zeros(5), np.zeros(5))
