"""Transition boundaries: a deviation below the command counts like one above, and a trial exactly
`points` samples long can already be past its transition."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.transition import command_on_input_base, remove_transition, transition_index
from protocol_runner.analysis.validation import AnalysisError


def test_a_joint_below_its_command_is_judged_by_the_size_of_the_deviation() -> None:
    command = np.full(8, 50.0)
    measured = np.array([20.0, 30.0, 46.0, 45.0, 47.0, 50.0, 50.0, 50.0])  # 4, 5, 3 deg below from sample 2
    assert transition_index(command, measured, tolerance_deg=5.0, points=3) == 2
    assert (
        transition_index(command, 2 * command - measured, tolerance_deg=5.0, points=3) == 2
    )  # mirrored above


def test_a_trial_exactly_points_long_that_follows_from_the_start() -> None:
    assert transition_index(np.zeros(3), np.array([1.0, -1.0, 0.5]), points=3) == 0
    with pytest.raises(AnalysisError, match=r"closest approach 0\.50 deg over 2 samples"):
        transition_index(np.zeros(2), np.array([-0.5, 1.0]), points=3)


def test_ticks_that_run_backwards_are_refused() -> None:
    with pytest.raises(AnalysisError, match="strictly increasing"):
        command_on_input_base([0.0, 0.02, 0.01], [1.0, 2.0, 3.0], [0.0, 0.005])


def test_a_negative_tolerance_is_refused_and_any_positive_one_accepted() -> None:
    with pytest.raises(AnalysisError, match="positive"):
        transition_index(np.zeros(5), np.zeros(5), tolerance_deg=-1.0)
    assert transition_index(np.zeros(5), np.full(5, 0.4), tolerance_deg=0.5) == 0


def test_removing_the_transition_uses_the_thesis_five_degrees_by_default() -> None:
    error = np.array([20.0, 20.0, 20.0, 5.5, 5.5, 5.5, 4.5, 4.5, 4.5, 0.0, 0.0, 0.0])
    n = error.size
    seg = remove_transition(np.arange(n) * 1e-3, np.zeros(n), error, np.zeros(n))
    assert seg.start_index == 6
