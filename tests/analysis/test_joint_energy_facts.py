"""Facts about the energy lost per cycle by several joints moved together (analysis/joint_energy.py): the
k-th cycle's total is the sum of every joint's k-th complete cycle of the same trial, for k up to the
fewest cycles any joint completed in that trial."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.joint_energy import total_energy_per_cycle


def _arrays(*values: list[float]) -> list[np.ndarray]:
    return [np.asarray(v, dtype=np.float64) for v in values]


def _trials(*values: list[int]) -> list[np.ndarray]:
    return [np.asarray(v, dtype=np.int64) for v in values]


def test_each_cycle_total_sums_every_joints_cycle_of_that_order_in_its_trial() -> None:
    """Hip: 3 cycles in trial 1, 2 in trial 2; knee: 2 in trial 1 (the transition removal cost it one),
    3 in trial 2.  Each trial counts the fewest cycles any joint completed, paired in order."""
    hip = [1.0, 2.0, 3.0, 4.0, 5.0]
    knee = [10.0, 20.0, 40.0, 50.0, 60.0]
    total, trial = total_energy_per_cycle(_arrays(hip, knee), _trials([1, 1, 1, 2, 2], [1, 1, 2, 2, 2]))
    np.testing.assert_allclose(total, [11.0, 22.0, 44.0, 55.0])
    np.testing.assert_array_equal(trial, [1, 1, 2, 2])
    assert total.dtype == np.float64 and trial.dtype == np.int64


def test_the_total_is_the_sum_over_the_joints_not_over_the_cycles() -> None:
    """Three joints with two cycles each in one trial: two totals (one per cycle), each the sum of the
    three joints' cycle energies."""
    total, trial = total_energy_per_cycle(
        _arrays([1.0, 2.0], [10.0, 20.0], [100.0, 200.0]), _trials([3, 3], [3, 3], [3, 3])
    )
    np.testing.assert_allclose(total, [111.0, 222.0])
    np.testing.assert_array_equal(trial, [3, 3])


def test_a_trial_in_which_one_joint_completed_no_cycle_gives_no_total() -> None:
    total, trial = total_energy_per_cycle(_arrays([1.0, 2.0, 3.0], [10.0, 20.0]), _trials([1, 2, 2], [2, 2]))
    np.testing.assert_allclose(total, [12.0, 23.0])
    np.testing.assert_array_equal(trial, [2, 2])


def test_trials_come_out_in_increasing_order_whatever_order_they_come_in() -> None:
    total, trial = total_energy_per_cycle(_arrays([5.0, 1.0], [50.0, 10.0]), _trials([2, 1], [2, 1]))
    np.testing.assert_allclose(total, [11.0, 55.0])
    np.testing.assert_array_equal(trial, [1, 2])


def test_a_single_joint_is_its_own_total_and_no_joint_gives_nothing() -> None:
    total, trial = total_energy_per_cycle(_arrays([0.5, 0.7, 0.9]), _trials([4, 4, 5]))
    np.testing.assert_allclose(total, [0.5, 0.7, 0.9])
    np.testing.assert_array_equal(trial, [4, 4, 5])
    total, trial = total_energy_per_cycle([], [])
    assert total.size == 0 and trial.size == 0


def test_every_joint_needs_its_cycles_trials() -> None:
    with pytest.raises(ValueError):
        total_energy_per_cycle(_arrays([1.0], [2.0]), _trials([1]))
