"""Branch labels on hand-made angle sequences whose turning points and branches are known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.branches import (
    LOADING,
    UNLOADING,
    branch_curves,
    branch_labels,
    complete_branches,
    turning_points,
)
from protocol_runner.analysis.validation import AnalysisError

L, U = LOADING, UNLOADING


def test_a_rise_fall_rise_has_its_extrema_as_turning_points_and_each_on_the_branch_ending_there() -> None:
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0])
    assert turning_points(x, 1.0).tolist() == [4, 8]
    # the maximum (sample 4) ends the loading branch; the minimum (sample 8) ends the unloading branch
    assert branch_labels(x, 1.0).tolist() == [L, L, L, L, L, U, U, U, U, L, L]


def test_a_trial_starting_downwards_begins_unloading() -> None:
    x = np.array([4.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 3.0, 2.0, 1.0])
    assert turning_points(x, 1.0).tolist() == [4, 7]
    assert branch_labels(x, 1.0).tolist() == [U, U, U, U, U, L, L, L, U, U]


def test_a_reversal_of_exactly_the_threshold_counts_and_a_smaller_one_does_not() -> None:
    exact = np.array([0.0, 2.0, 4.0, 3.0, 5.0, 7.0])  # falls back 1.0 deg from the 4 deg peak
    assert turning_points(exact, 1.0).tolist() == [2, 3]
    short = np.array([0.0, 2.0, 4.0, 3.5, 5.0, 7.0])  # falls back only 0.5 deg
    assert turning_points(short, 1.0).size == 0
    assert branch_labels(short, 1.0).tolist() == [L] * 6


def test_first_and_last_samples_are_never_turning_points() -> None:
    x = np.array([5.0, 0.0, 5.0, 0.0, 5.0])
    assert turning_points(x, 1.0).tolist() == [1, 2, 3]
    assert branch_labels(x, 1.0).tolist() == [U, U, L, U, L]


def test_a_monotonic_fall_is_unloading_throughout() -> None:
    x = np.linspace(90.0, 10.0, 50)
    assert branch_labels(x).tolist() == [U] * 50
    assert branch_labels(x[::-1]).tolist() == [L] * 50


def test_a_linear_spring_with_coulomb_friction_is_recovered_exactly_on_each_branch() -> None:
    # torque = 0.5 (angle - 20) + 3 N m loading, - 3 N m unloading; bin means of points on a line lie on it
    t = np.arange(0.0, 30.0, 0.01)
    angle = 60.0 - 40.0 * np.cos(2 * np.pi * t / 7.5)
    lab = branch_labels(angle)
    torque = 0.5 * (angle - 20.0) + 3.0 * lab
    curves = branch_curves(angle, torque)
    probe = np.array([25.0, 50.0, 90.0])
    np.testing.assert_allclose(curves.torque_at(probe, np.full(3, L)), 0.5 * (probe - 20.0) + 3.0, atol=1e-9)
    np.testing.assert_allclose(curves.torque_at(probe, np.full(3, U)), 0.5 * (probe - 20.0) - 3.0, atol=1e-9)
    # each branch covers the swept range, ends included
    assert curves.loading_angle_deg[0] == pytest.approx(20.0, abs=0.3)
    assert curves.unloading_angle_deg[-1] == pytest.approx(100.0, abs=0.3)
    ends = np.array([curves.loading_angle_deg[0], curves.loading_angle_deg[-1]])
    assert curves.covers(ends, np.full(2, L)).all()
    assert not curves.covers(ends - np.array([1e-6, -1e-6]), np.full(2, L)).any()


def test_each_curve_point_is_the_mean_of_one_bin_width_of_samples() -> None:
    # one sweep up 10 -> 30 deg and back, samples every 0.25 deg: 2 deg bins hold 8 samples each
    up = np.arange(10.0, 30.0, 0.25)
    angle = np.concatenate([up, up[::-1]])
    torque = angle**2  # curvature: a bin's mean torque is not the torque at its mean angle
    curves = branch_curves(angle, torque, bin_width_deg=2.0)
    assert curves.loading_angle_deg.size == 10
    np.testing.assert_allclose(curves.loading_angle_deg, 10.875 + 2.0 * np.arange(10))
    first_bin = np.arange(10.0, 12.0, 0.25)
    assert curves.loading_torque_nm[0] == pytest.approx(np.mean(first_bin**2))


def test_a_zero_bin_width_is_a_user_error() -> None:
    angle = np.linspace(0.0, 40.0, 50)
    with pytest.raises(AnalysisError, match="bin width must be positive"):
        branch_curves(np.concatenate([angle, angle[::-1]]), np.zeros(100), bin_width_deg=0.0)


def test_the_default_reversal_is_one_degree() -> None:
    """A 1.5 deg fall back confirms a maximum, a 0.5 deg one does not."""
    x = np.array([0.0, 1.0, 2.0, 3.0, 1.5, 2.5, 2.0, 5.0, 6.0])
    assert turning_points(x).tolist() == [3, 4]
    np.testing.assert_array_equal(branch_labels(x), branch_labels(x, 1.0))


def test_the_complete_branches_run_from_the_first_turning_point_to_the_last_inclusive() -> None:
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 3.0])
    assert complete_branches(x, 1.0) == slice(5, 11)  # the maximum at 5 through the minimum at 10
    assert complete_branches(x[:9], 1.0) == slice(None)  # one turning point: no complete branch, all kept
