"""Equal-time subtraction needs a brace-off clock that runs forward; one sample is a constant. Called alone,
equal-angle subtraction gives what the pipeline gives with its default settings."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.analysis.subtraction import (
    robot_torque_at_equal_angle,
    subtract_equal_angle,
    subtract_equal_time,
)
from protocol_runner.analysis.validation import AnalysisError


def test_a_brace_off_clock_that_stalls_or_runs_back_is_refused() -> None:
    for t_off in ([0.0, 0.1, 0.1], [0.0, 0.2, 0.1], [0.2, 0.1]):
        with pytest.raises(AnalysisError, match="time_off_s must be strictly increasing"):
            subtract_equal_time([0.0, 0.1], [1.0, 1.0], t_off, np.arange(float(len(t_off))))


def test_a_single_brace_off_sample_is_subtracted_as_a_constant() -> None:
    out = subtract_equal_time([3.0, 3.1, 3.2], [5.0, 6.0, 7.0], [8.0], [2.0])
    np.testing.assert_allclose(out, [3.0, 4.0, 5.0])


def test_called_alone_the_subtraction_uses_the_processing_defaults() -> None:
    s = ProcessingSettings()
    t = np.arange(0.0, 16.0, 0.01)
    a_off = 60.0 + 45.0 * np.sin(2 * np.pi * t / 8.0)
    a_on = (
        60.0 + 35.0 * np.sin(2 * np.pi * t / 8.0 + 0.3) + 0.8 * np.sin(2 * np.pi * t / 0.37)
    )  # small wiggles
    q_off = 30.0 * np.sin(np.radians(a_off)) + 4.0 * np.sign(np.cos(2 * np.pi * t / 8.0)) + 0.05 * a_off**1.5
    q_on = q_off[::-1].copy()
    alone = subtract_equal_angle(a_on, q_on, a_off, q_off)
    explicit = subtract_equal_angle(
        a_on,
        q_on,
        a_off,
        q_off,
        bin_width_deg=s.bin_width_deg,
        reversal_deg=s.reversal_deg,
        outside=s.outside,
    )
    np.testing.assert_array_equal(alone, explicit)
    robot, covered = robot_torque_at_equal_angle(a_on, a_off, q_off)
    np.testing.assert_array_equal(q_on - robot, explicit)
    assert covered.all()
    # and the defaults matter here: other values give other numbers
    assert not np.array_equal(alone, subtract_equal_angle(a_on, q_on, a_off, q_off, bin_width_deg=1.5))
    assert not np.array_equal(alone, subtract_equal_angle(a_on, q_on, a_off, q_off, reversal_deg=2.0))
