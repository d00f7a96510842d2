"""Facts the generalised Bouc-Wen fit's reported numbers must obey (thesis §6.2): R^2 is the textbook
coefficient of determination, errors are per sample, and a held-out trial is never part of its own fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.models.bouc_wen.fitting import cross_validate, fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
STIFFER = BoucWenParams(A=0.6, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _sweep(periods: float, phase: float = 0.0, amplitude: float = 60.0) -> np.ndarray:
    t = np.arange(0.0, periods * 8.17, 0.05)
    return amplitude * np.sin(2 * np.pi * t / 8.17 + phase)


def test_r2_is_one_minus_sse_over_the_centred_total_sum_of_squares() -> None:
    # a torque offset of 40 N m: an uncentred total sum of squares would make R^2 look almost perfect
    rng = np.random.default_rng(7)
    segments = []
    for k, amplitude in enumerate((60.0, 45.0)):
        x = _sweep(1.5, 0.4 * k, amplitude)
        y = 40.0 + simulate(x, FIG57, z0=0.0) + rng.normal(0.0, 1.5, x.size)
        segments.append((x, y))
    result = fit_trials(segments, starts=1)
    y_all = np.concatenate([y for _, y in segments])
    n = y_all.size
    sse = result.rmse_nm**2 * n
    assert result.r2 == pytest.approx(1.0 - sse / np.sum((y_all - y_all.mean()) ** 2), rel=1e-9)
    # the overall RMSE pools the per-trial errors sample by sample
    pooled = sum(r**2 * y.size for r, (_, y) in zip(result.trial_rmse_nm, segments, strict=True))
    assert sse == pytest.approx(pooled, rel=1e-9)
    assert result.n_samples == n
    assert 0.0 < result.r2 < 1.0


def test_a_held_out_trial_unlike_the_others_has_the_error_of_the_others_model() -> None:
    """Trials 0 and 1 follow Figure 57 exactly, trial 2 a stiffer joint.  Held out, trial 2 is predicted by
    the model of trials 0 and 1 alone - Figure 57 itself - so its error is Figure 57's error on trial 2,
    far above the others' (a fit that saw trial 2 would do better on it)."""
    x = [_sweep(1.5, 0.0), _sweep(1.5, 0.5), _sweep(1.5, 1.0)]
    y = [simulate(x[0], FIG57, z0=0.0), simulate(x[1], FIG57, z0=1.0), simulate(x[2], STIFFER, z0=0.0)]
    segments = list(zip(x, y, strict=True))
    errors = cross_validate(segments, starts=2)
    expected = math.sqrt(float(np.mean((simulate(x[2], FIG57, z0=y[2][0]) - y[2]) ** 2)))
    assert expected > 1.0
    assert errors[2] == pytest.approx(expected, rel=1e-3)
    assert errors[2] > 1.5 * max(errors[0], errors[1])
    # the fit on all three trials, which does see trial 2, is closer to it than the held-out prediction
    full = fit_trials(segments, starts=2)
    assert full.trial_rmse_nm[2] < 0.8 * errors[2]


def test_parameter_uncertainties_are_the_least_squares_covariance() -> None:
    """param_std = sqrt(diag(s^2 (J^T J)^-1)), s^2 = SSE / (m - 8), J the derivative of the simulated torque
    with respect to (A, n, beta1..6) - here by central differences of `simulate`."""
    rng = np.random.default_rng(5)
    segments = []
    for k in range(2):
        x = _sweep(1.5, 0.7 * k)
        segments.append((x, simulate(x, FIG57, z0=0.0) + rng.normal(0.0, 0.3, x.size)))
    result = fit_trials(segments, starts=1)
    assert result.n_samples_fitted == result.n_samples  # no decimation: the covariance is on every sample
    p = result.params.as_array()
    columns = []
    for j in range(8):
        h = 1e-6 * max(abs(p[j]), 1e-3)
        up, down = p.copy(), p.copy()
        up[j] += h
        down[j] -= h
        col = [
            (
                simulate(x, BoucWenParams.from_array(up), z0=y[0])
                - simulate(x, BoucWenParams.from_array(down), z0=y[0])
            )
            / (2 * h)
            for x, y in segments
        ]
        columns.append(np.concatenate(col))
    J = np.column_stack(columns)
    m = J.shape[0]
    s2 = result.rmse_nm**2 * m / (m - 8)
    expected = np.sqrt(np.diag(s2 * np.linalg.inv(J.T @ J)))
    np.testing.assert_allclose(result.param_std, expected, rtol=1e-3)


def test_r2_is_undefined_without_torque_variance_and_defined_for_small_torques() -> None:
    x = _sweep(1.5)
    flat = fit_trials([(x, np.full(x.size, 3.0))], starts=1)
    assert math.isnan(flat.r2)  # the total sum of squares is zero
    small = 0.002 * simulate(x, FIG57, z0=0.0)  # total sum of squares well below 1 (N m)^2
    result = fit_trials([(x, small)], starts=1)
    assert np.sum((small - small.mean()) ** 2) < 1.0
    assert result.r2 == pytest.approx(1.0, abs=1e-6)
