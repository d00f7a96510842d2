"""Transition detection and removal (thesis §3.3.1) and command resampling onto the input time base."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.transition import (
    command_on_input_base,
    remove_transition,
    transition_index,
)
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.errors import InvalidInput

from .synth import first_order_lag, sine_command


def test_transition_is_first_run_of_points_within_tolerance() -> None:
    command = np.zeros(300)
    error = np.full(300, 20.0)
    error[100] = 1.0  # a single sample within tolerance: not enough for three points
    error[150:] = 4.0  # within 5 deg from here on
    measured = command + error
    assert transition_index(command, measured, tolerance_deg=5.0, points=3) == 150
    assert transition_index(command, measured, tolerance_deg=5.0, points=1) == 100


def test_transition_tolerance_boundary_is_inclusive() -> None:
    command = np.zeros(10)
    measured = np.array([9.0, 9.0, 5.0, 5.0, 5.0, 9.0, 9.0, 9.0, 9.0, 9.0])
    assert transition_index(command, measured, tolerance_deg=5.0, points=3) == 2
    with pytest.raises(AnalysisError):
        transition_index(command, measured, tolerance_deg=4.99, points=3)


def test_transition_of_a_lagging_joint_starting_from_park() -> None:
    # The joint is parked at 0 deg and the trajectory starts at 65 deg: it follows after a lag.
    t, cmd = sine_command(65.0, 60.0, 8.0, 10.0, 1000.0)
    measured = first_order_lag(cmd, 1e-3, 0.2, 0.0)
    i = transition_index(cmd, measured)
    assert np.all(np.abs(measured[i : i + 3] - cmd[i : i + 3]) <= 5.0)
    assert np.all(np.abs(measured[:i] - cmd[:i]) > 5.0) or i == 0
    assert 0.1 < t[i] < 2.0  # tau = 0.2 s: reached within a few time constants, not at once


def test_transition_never_reached_is_a_clear_user_error() -> None:
    command = np.zeros(100)
    measured = np.full(100, 30.0)
    with pytest.raises(AnalysisError, match="transition never ends") as info:
        transition_index(command, measured)
    assert isinstance(info.value, InvalidInput)
    assert "30.00 deg" in str(info.value)


def test_transition_rejects_mismatched_lengths_and_bad_parameters() -> None:
    with pytest.raises(AnalysisError, match="same number of samples"):
        transition_index(np.zeros(10), np.zeros(11))
    with pytest.raises(AnalysisError, match="positive"):
        transition_index(np.zeros(10), np.zeros(10), tolerance_deg=0.0)
    with pytest.raises(AnalysisError, match="at least 1"):
        transition_index(np.zeros(10), np.zeros(10), points=0)
    with pytest.raises(AnalysisError, match="not a finite number"):
        transition_index(np.array([0.0, np.nan]), np.zeros(2))


def test_zero_order_hold_keeps_each_tick_until_the_next() -> None:
    tick_t = np.array([0.0, 0.01, 0.02])
    tick_v = np.array([1.0, 2.0, 3.0])
    t_in = np.array([-0.001, 0.0, 0.005, 0.0099, 0.01, 0.015, 0.02, 0.05])
    held = command_on_input_base(tick_t, tick_v, t_in, "hold")
    np.testing.assert_array_equal(held, [1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0])


def test_linear_resampling_interpolates_between_ticks() -> None:
    tick_t = np.array([0.0, 0.01, 0.02])
    tick_v = np.array([1.0, 2.0, 4.0])
    lin = command_on_input_base(tick_t, tick_v, np.array([0.005, 0.015, 0.03]), "linear")
    np.testing.assert_allclose(lin, [1.5, 3.0, 4.0])


def test_resampling_rejects_unordered_ticks_and_unknown_method() -> None:
    with pytest.raises(AnalysisError, match="strictly increasing"):
        command_on_input_base([0.0, 0.0], [1.0, 2.0], [0.0])
    with pytest.raises(AnalysisError, match="unknown command resampling"):
        command_on_input_base([0.0, 1.0], [1.0, 2.0], [0.0], "cubic")  # type: ignore[arg-type]


def test_remove_transition_cuts_every_signal_at_the_same_index() -> None:
    n = 50
    t = np.arange(n) * 1e-3
    cmd = np.full(n, 10.0)
    angle = np.where(np.arange(n) < 20, 40.0, 11.0)
    torque = np.arange(n, dtype=float)
    seg = remove_transition(t, cmd, angle, torque)
    assert seg.start_index == 20
    np.testing.assert_array_equal(seg.time_s, t[20:])  # original clock kept
    np.testing.assert_array_equal(seg.torque_nm, torque[20:])
    np.testing.assert_array_equal(seg.angle_deg, angle[20:])
    np.testing.assert_array_equal(seg.command_deg, cmd[20:])
