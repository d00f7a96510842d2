"""Loading / unloading branches and per-branch angle -> torque curves (used by thesis §3.3 subtraction)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.branches import (
    LOADING,
    UNLOADING,
    branch_curves,
    branch_labels,
    turning_points,
)
from protocol_runner.analysis.validation import AnalysisError


def _sine(noise_deg: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 20.0, 1e-3)
    angle = 60.0 + 40.0 * np.sin(2 * np.pi * t / 4.0)
    if noise_deg:
        angle = angle + np.random.default_rng(seed).normal(0.0, noise_deg, t.shape)
    return t, angle


def test_turning_points_are_the_extrema_of_the_sine() -> None:
    t, angle = _sine()
    turns = turning_points(angle)
    # maxima at t = 1, 5, 9, ...; minima at t = 3, 7, ...: 5 maxima and 5 minima in 20 s
    expected = np.arange(1.0, 20.0, 2.0)
    np.testing.assert_allclose(t[turns], expected, atol=2e-3)
    assert np.all(np.diff(angle[turns][::2]) == pytest.approx(0.0, abs=1e-6))  # all maxima at the same height


def test_noise_below_the_reversal_threshold_adds_no_turning_points() -> None:
    t, angle = _sine(noise_deg=0.1, seed=3)
    turns = turning_points(angle, reversal_deg=1.0)
    assert turns.size == 10
    np.testing.assert_allclose(t[turns], np.arange(1.0, 20.0, 2.0), atol=0.15)
    # the naive sign of the sample-to-sample derivative would flip thousands of times on this signal
    assert np.count_nonzero(np.diff(np.sign(np.diff(angle)))) > 1000


def test_labels_follow_the_direction_of_motion() -> None:
    t, angle = _sine(noise_deg=0.1, seed=4)
    labels = branch_labels(angle)
    velocity = np.cos(2 * np.pi * t / 4.0)  # sign of the clean derivative
    clear = np.abs(velocity) > 0.2  # away from the turning points
    np.testing.assert_array_equal(labels[clear], np.where(velocity[clear] > 0, LOADING, UNLOADING))


def test_monotonic_signal_is_a_single_branch() -> None:
    assert set(branch_labels(np.linspace(0.0, 10.0, 50)).tolist()) == {LOADING}
    assert set(branch_labels(np.linspace(10.0, 0.0, 50)).tolist()) == {UNLOADING}


def test_branch_curves_separate_a_friction_loop() -> None:
    t, angle = _sine()
    velocity = np.cos(2 * np.pi * t / 4.0)
    torque = 0.5 * angle + 3.0 * np.sign(velocity)
    curves = branch_curves(angle, torque, bin_width_deg=0.5)
    grid = np.linspace(25.0, 95.0, 50)
    np.testing.assert_allclose(curves.torque_at(grid, np.full(50, LOADING)), 0.5 * grid + 3.0, atol=0.05)
    np.testing.assert_allclose(curves.torque_at(grid, np.full(50, UNLOADING)), 0.5 * grid - 3.0, atol=0.05)


def test_outside_the_covered_range_clip_or_nan() -> None:
    angle = np.concatenate([np.linspace(10, 50, 200), np.linspace(50, 10, 200)])
    torque = angle.copy()
    curves = branch_curves(angle, torque, bin_width_deg=1.0)
    probe = np.array([0.0, 30.0, 80.0])
    labels = np.full(3, LOADING)
    clipped = curves.torque_at(probe, labels, "clip")
    assert clipped[0] == pytest.approx(curves.loading_torque_nm[0])
    assert clipped[2] == pytest.approx(curves.loading_torque_nm[-1])
    nan = curves.torque_at(probe, labels, "nan")
    assert np.isnan(nan[0]) and np.isnan(nan[2]) and nan[1] == pytest.approx(30.0, abs=0.5)
    np.testing.assert_array_equal(curves.covers(probe, labels), [False, True, False])


def test_a_trial_without_an_unloading_branch_cannot_be_a_reference() -> None:
    angle = np.linspace(0.0, 90.0, 500)
    with pytest.raises(AnalysisError, match="no usable unloading branch"):
        branch_curves(angle, np.zeros(500))


def test_reversal_threshold_must_be_positive() -> None:
    with pytest.raises(AnalysisError, match="positive"):
        turning_points(np.zeros(10), reversal_deg=0.0)
