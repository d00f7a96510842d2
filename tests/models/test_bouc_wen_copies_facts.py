"""Facts of the turning-point copy (models/bouc_wen/copies.py): it keeps every sample where the angle stops or
turns, compares every stride-th sample, and the Bouc-Wen state integrated along it is the state along every
sample (Eq 20 depends on the angle travelled, not on when), which a plain every-k-th-sample copy is not when
the angle has small reversals."""

from __future__ import annotations

import numpy as np

from protocol_runner.models.bouc_wen import BoucWenParams, simulate
from protocol_runner.models.bouc_wen.copies import decimate, turning_point_copy

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
