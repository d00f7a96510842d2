"""Facts of the turning-point copy (models/bouc_wen/copies.py): it keeps every sample where the angle stops or
turns, compares every stride-th sample, and the Bouc-Wen state integrated along it is the state along every
sample (Eq 20 depends on the angle travelled, not on when), which a plain every-k-th-sample copy is not when
the angle has small reversals."""

from __future__ import annotations

import numpy as np

from protocol_runner.models.bouc_wen.copies import decimate, turning_point_copy
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _dithered_sweep(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A +-60 deg sweep at 200 Hz with 0.05 deg of angle noise (many small reversals at the slow ends)."""
    t = np.arange(0.0, 16.34, 0.005)
    x = 60.0 * np.sin(2.0 * np.pi * t / 8.17) + np.random.default_rng(seed).normal(0.0, 0.05, t.size)
    return x, simulate(x, FIG57, 0.0)


def test_the_copy_keeps_every_turning_point_and_compares_every_stride_th_sample() -> None:
    trials = [_dithered_sweep(0), _dithered_sweep(1)]
    copy = turning_point_copy(trials, 400)
    assert copy.rows is not None
    start = 0
    for k, (x, y) in enumerate(trials):
        stride = -(-x.size // 400)
        kept_x = copy.x[copy.seg[k] : copy.seg[k + 1]]
        d = np.diff(x)
        turns = x[1:-1][d[:-1] * d[1:] <= 0.0]
        assert turns.size > 100  # the noise reverses the angle often
        assert np.isin(turns, kept_x).all() and kept_x[-1] == x[-1]
        rows = copy.rows[(copy.rows >= copy.seg[k]) & (copy.rows < copy.seg[k + 1])]
        np.testing.assert_array_equal(copy.x[rows], x[::stride])
        np.testing.assert_array_equal(copy.y[rows], y[::stride])
        start += x.size
    assert copy.x.size < 0.5 * start  # far fewer samples than the trials


def test_the_state_along_the_copy_is_the_state_along_every_sample() -> None:
    """At the compared samples the torque simulated along the turning-point copy agrees with the torque
    simulated along every sample within 0.1 % of the torque range; along every k-th sample alone (the
    small reversals cut) it misses by ten times more."""
    x, _ = _dithered_sweep(2)
    full = simulate(x, FIG57, 0.0)
    copy = turning_point_copy([(x, full)], 400)
    assert copy.rows is not None
    along_copy = simulate(copy.x, FIG57, 0.0)[copy.rows]
    xs, _, _, (stride,) = decimate([(x, full)], 400)
    along_stride = simulate(xs, FIG57, 0.0)
    scale = float(np.ptp(full))
    copy_error = float(np.max(np.abs(along_copy - full[::stride])))
    stride_error = float(np.max(np.abs(along_stride - full[::stride])))
    assert copy_error < 1e-3 * scale
    assert stride_error > 10.0 * copy_error


def _trial(x: list[float]) -> tuple[np.ndarray, np.ndarray]:
    a = np.array(x, dtype=float)
    return a, 10.0 * a + 1.0


def test_a_copy_keeps_where_the_angle_stops_or_turns_and_its_last_sample_in_each_trial() -> None:
    # 11 samples, at most 3 compared: stride 4 (samples 0, 4, 8); the angle stops between samples 3 and 4
    # (both kept: the step before or after is zero), turns at sample 6, and ends at sample 10
    first = _trial([0, 1, 2, 3, 3, 4, 5, 4, 3, 2, 1.5])
    second = _trial([5, 6, 7, 8, 7, 6, 5])  # stride 3 (samples 0, 3, 6); turns at sample 3
    copy = turning_point_copy([first, second], 3)
    np.testing.assert_array_equal(copy.x, [0, 3, 3, 5, 3, 1.5, 5, 8, 5])
    np.testing.assert_array_equal(copy.y, 10.0 * copy.x + 1.0)
    np.testing.assert_array_equal(copy.seg, [0, 6, 9])
    assert copy.rows is not None
    np.testing.assert_array_equal(copy.rows, [0, 2, 4, 6, 7, 8])  # samples 0, 4, 8 and 0, 3, 6 of the trials
    whole = turning_point_copy([first, second], 11)  # room for every sample: stride 1, all compared
    np.testing.assert_array_equal(whole.x, np.concatenate([first[0], second[0]]))
    np.testing.assert_array_equal(whole.rows, np.arange(18))


def test_decimate_keeps_every_stride_th_sample_of_each_trial_with_its_own_stride() -> None:
    first = _trial(list(range(10)))
    second = _trial([20, 21, 22, 23, 24, 25, 26])
    x, y, seg, strides = decimate([first, second], 3)
    assert strides == (4, 3)  # ceil(10 / 3), ceil(7 / 3)
    np.testing.assert_array_equal(x, [0, 4, 8, 20, 23, 26])
    np.testing.assert_array_equal(y, 10.0 * x + 1.0)
    np.testing.assert_array_equal(seg, [0, 3, 6])
    x_all, _, seg_all, strides_all = decimate([first, second], None)
    assert strides_all == (1, 1) and x_all.size == 17
    np.testing.assert_array_equal(seg_all, [0, 10, 17])


def test_the_path_problem_integrates_every_sample_and_compares_every_stride_th() -> None:
    from protocol_runner.models.bouc_wen.copies import _path_problem
    from protocol_runner.models.bouc_wen.problem import FitScale
    from protocol_runner.models.bouc_wen.records import BoucWenBounds

    first = _trial(list(range(10)))
    second = _trial([20, 21, 22, 23, 24, 25, 26])
    problem = _path_problem([first, second], (4, 3), BoucWenBounds(), FitScale(26.0, 261.0), None)
    assert problem.x.size == 17
    np.testing.assert_array_equal(problem.seg, [0, 10, 17])
    assert problem.rows is not None
    np.testing.assert_array_equal(problem.rows, [0, 4, 8, 10, 13, 16])
