"""The refined kernels integrate all of a fit's trials in one call, each from its own starting torque: each
trial's torque, derivatives and divergence must be bit for bit what integrating that trial alone gives,
whatever the trials' lengths, their number, zero crossings, divergence (held at the bound or NaN) and the
rows compared."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.kernels import IDENTITY8, NO_SENSITIVITY, kernel
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate, simulate_trials

SHAPE = (1.2, 1.4, np.array([0.3, 0.1, -0.05, 0.4, 0.2, -0.1]))
STEEP = (1.2, 1.4, np.array([-0.9, 0.0, 0.0, -0.9, 0.0, 0.0]))  # |z| grows without limit: diverges
STABLE = (1.0, 1.5, np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0]))  # saturates (|z| < 2^(2/3)): never diverges


def _trial(rng: np.random.Generator, n: int, amplitude: float) -> np.ndarray:
    """A sampled loop through zero with uneven steps, repeated angles and a few reversals."""
    t = np.sort(rng.uniform(0.0, 4.0 * np.pi, n))
    x = amplitude * np.sin(t)
    x[n // 3] = x[n // 3 - 1]  # a repeated sample: no piece
    return x


def _run(xs, z0s, shape, bound, freeze, stop, rows_every, T):
    x = np.concatenate(xs)
    seg = np.concatenate([[0], np.cumsum([len(v) for v in xs])]).astype(np.int64)
    rows = np.arange(0, x.size, rows_every, dtype=np.int64)
    z = np.full(x.size, 7.0)
    dz = np.full((rows.size, 8), 3.0)
    bad = kernel(x, seg, np.asarray(z0s), shape, (bound, freeze, 0.25, stop), z, (dz, T, rows), True, True)
    return bad, z, dz, seg, rows


def _alone(xs, z0s, shape, bound, freeze, rows_every, T):
    """Each trial integrated by itself: the reference, stitched into the rows of the joint call."""
    x = np.concatenate(xs)
    seg = np.concatenate([[0], np.cumsum([len(v) for v in xs])]).astype(np.int64)
    rows = np.arange(0, x.size, rows_every, dtype=np.int64)
    z = np.empty(x.size)
    dz = np.empty((rows.size, 8))
    firsts = []
    for k, v in enumerate(xs):
        bad, zk, dzk, _, _ = _run([v], [z0s[k]], shape, bound, freeze, False, 1, T)
        z[seg[k] : seg[k + 1]] = zk
        mine = (rows >= seg[k]) & (rows < seg[k + 1])
        dz[mine] = dzk[rows[mine] - seg[k]]
        if bad >= 0:
            firsts.append(seg[k] + bad)
    return (min(firsts) if firsts else -1), z, dz


@pytest.mark.parametrize("n_trials", [1, 2, 3, 4, 5, 6, 7])
@pytest.mark.parametrize("freeze", [True, False])
def test_trials_integrated_together_are_bit_for_bit_each_trial_alone(n_trials: int, freeze: bool) -> None:
    rng = np.random.default_rng(n_trials)
    xs = [_trial(rng, int(rng.integers(40, 90)), 30.0 + 5.0 * k) for k in range(n_trials)]
    z0s = [0.5 * (-1) ** k for k in range(n_trials)]
    T = rng.normal(size=(8, 8))
    for shape, bound in ((SHAPE, 50.0), (STABLE, 10.0), (STEEP, 8.0)):
        ref_bad, ref_z, ref_dz = _alone(xs, z0s, shape, bound, freeze, 3, T)
        bad, z, dz, _, _ = _run(xs, z0s, shape, bound, freeze, False, 3, T)
        assert bad == ref_bad
        np.testing.assert_array_equal(z, ref_z)  # NaN where diverged without freezing, in both
        np.testing.assert_array_equal(dz, ref_dz)
    assert ref_bad > 0  # the steep shape did diverge: the held / NaN path was compared too


def test_a_check_that_stops_at_divergence_reports_the_first_in_trial_order() -> None:
    """With `stop`, the index returned is the first diverged sample in trial order (a short fast trial that
    diverges within a few samples beside a long slow one), and -1 when none diverges."""
    rng = np.random.default_rng(7)
    slow = _trial(rng, 120, 6.0)  # small excursion: diverges late, if at all
    fast = np.linspace(0.0, 60.0, 30)  # one long push: diverges within a few samples
    cases = [[slow, fast], [fast, slow], [slow, slow, fast], [slow, fast, fast], [slow, fast, slow]]
    cases += [[fast, slow, slow], [slow, slow, slow, fast], [slow, slow, slow, slow, fast]]
    for xs in cases:
        z0s = [0.0] * len(xs)
        ref_bad, _, _ = _alone(xs, z0s, STEEP, 8.0, True, 1, IDENTITY8)
        bad, _, _, _, _ = _run(xs, z0s, STEEP, 8.0, True, True, 1, IDENTITY8)
        assert bad == ref_bad >= 0
    for xs in ([slow, slow], [slow, slow, slow]):
        ref_bad, _, _ = _alone(xs, [0.0] * len(xs), STABLE, 10.0, True, 1, IDENTITY8)
        bad, _, _, _, _ = _run(xs, [0.0] * len(xs), STABLE, 10.0, True, True, 1, IDENTITY8)
        assert bad == ref_bad == -1


def _plain(xs, z0s, shape, bound, freeze, stop):
    x = np.concatenate(xs)
    seg = np.concatenate([[0], np.cumsum([len(v) for v in xs])]).astype(np.int64)
    z = np.full(x.size, 7.0)
    limits = (bound, freeze, 0.25, stop)
    bad = kernel(x, seg, np.asarray(z0s, dtype=np.float64), shape, limits, z, NO_SENSITIVITY, True, False)
    return bad, z, seg


@pytest.mark.parametrize("n_trials", [1, 2, 3, 4, 5, 6, 7])
@pytest.mark.parametrize("freeze", [True, False])
def test_the_kernel_without_derivatives_gives_each_trial_alone_bit_for_bit(
    n_trials: int, freeze: bool
) -> None:
    """The kernel without derivatives (evaluations, the 4x-finer check) takes several trials too: each
    trial's torque and the first diverged index are those of the trial alone, with or without stopping at
    the first divergence."""
    rng = np.random.default_rng(10 + n_trials)
    xs = [_trial(rng, int(rng.integers(40, 90)), 30.0 + 5.0 * k) for k in range(n_trials)]
    z0s = [0.5 * (-1) ** k for k in range(n_trials)]
    diverged = False
    for shape, bound in ((SHAPE, 50.0), (STABLE, 10.0), (STEEP, 8.0)):
        bad, z, seg = _plain(xs, z0s, shape, bound, freeze, False)
        firsts = []
        for k, v in enumerate(xs):
            bad_k, z_k, _ = _plain([v], [z0s[k]], shape, bound, freeze, False)
            np.testing.assert_array_equal(z[seg[k] : seg[k + 1]], z_k)  # NaN where diverged, in both
            if bad_k >= 0:
                firsts.append(seg[k] + bad_k)
        assert bad == (min(firsts) if firsts else -1)
        assert _plain(xs, z0s, shape, bound, freeze, True)[0] == bad
        diverged = diverged or bad >= 0
    assert diverged  # the steep shape did diverge: the held / NaN path was compared too


def test_simulating_several_trials_at_once_gives_each_trial_alone() -> None:
    """`simulate_trials` (the model torque of every trial of a fit, in one call) is `simulate` of each
    trial: the same bits, NaN from a divergence on in that trial only, float32 angles taken as simulate
    takes them; mismatched or non-finite starting torques are refused."""
    rng = np.random.default_rng(3)
    params = BoucWenParams(1.0, 1.5, (0.5, 0.0, 0.0, 0.0, 0.0, 0.0))  # saturates at |z| = 2^(2/3)
    xs = [_trial(rng, 60, 0.3).astype(np.float32), np.linspace(0.0, 60.0, 30), _trial(rng, 80, 0.5)]
    z0s = [0.2, 0.0, -0.3]
    together = simulate_trials(xs, params, z0s, bound_nm=1.2)  # the long push passes 1.2: diverged
    for x, z0, z in zip(xs, z0s, together, strict=True):
        np.testing.assert_array_equal(z, simulate(x, params, z0=z0, bound_nm=1.2))
    assert np.isnan(together[1][-1]) and np.all(np.isfinite(together[0])) and np.all(np.isfinite(together[2]))
    with pytest.raises(InvalidInput, match="2 trials but 1 starting torques"):
        simulate_trials(xs[:2], params, [0.0])
    with pytest.raises(InvalidInput, match="z0 must be a finite torque"):
        simulate_trials(xs[:1], params, [float("nan")])
