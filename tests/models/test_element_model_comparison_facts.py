"""Facts of the model comparison (analysis/model_comparison.py): AIC and BIC on the effective sample size,
leave-one-trial-out errors, and the Bouc-Wen functionals with their t-intervals over the trials."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.analysis.energy import energy_per_cycle
from protocol_runner.analysis.model_comparison import bouc_wen_functionals, compare_models
from tests.models.test_element_model_fit import _device, _trials


def test_aic_and_bic_weigh_the_fit_on_the_effective_samples() -> None:
    """For every model: AIC = n_eff ln(SSE / n) + 2k and BIC = n_eff ln(SSE / n) + k ln(n_eff), with
    SSE / n = RMSE^2 and n_eff the element fit's effective sample size (one for every model)."""
    comparison = compare_models(_trials(_device(), np.random.default_rng(4)), _device())
    assert comparison.element_fit is not None
    n_eff = comparison.element_fit.n_eff
    assert 10.0 < n_eff < comparison.element_fit.n_samples  # correlated residuals count for fewer samples
    for row in comparison.rows:
        fit_term = n_eff * math.log(row.rmse_nm**2)
        assert row.aic == pytest.approx(fit_term + 2 * row.k, rel=1e-9)
        assert row.bic == pytest.approx(fit_term + row.k * math.log(n_eff), rel=1e-9)


def test_one_trial_leaves_nothing_to_hold_out() -> None:
    comparison = compare_models(_trials(_device(), np.random.default_rng(5), trials=1), _device())
    assert all(math.isnan(row.heldout_rmse_nm) for row in comparison.rows)


def _loop(amplitude_deg: float, width_nm: float) -> tuple[np.ndarray, np.ndarray]:
    """An elliptic loop on a 0.2 N*m/deg slope from an angle's minimum: two complete cycles (upward
    crossings at 0, 2 pi and 4 pi) and most of a third."""
    phase = np.linspace(-0.5 * np.pi, 5.5 * np.pi, 1201)
    x = amplitude_deg * np.sin(phase)
    return x, 0.2 * x + width_nm * np.cos(phase)


def test_the_functionals_are_per_trial_values_with_a_t_interval_over_the_trials() -> None:
    loops = [_loop(40.0, w) for w in (2.0, 2.5, 3.5)]
    energy, half, slope = bouc_wen_functionals([(x, z) for x, z in loops], [z for _, z in loops])
    per_trial = [float(np.mean(energy_per_cycle(x, z))) for x, z in loops]
    mean = float(np.mean(per_trial))
    margin = stats.t.ppf(0.975, 2) * float(np.std(per_trial, ddof=1)) / math.sqrt(3)
    assert (energy.name, energy.unit) == ("loop energy per cycle", "J")
    assert energy.value == pytest.approx(mean, rel=1e-12)
    assert (energy.ci95_low, energy.ci95_high) == (pytest.approx(mean - margin), pytest.approx(mean + margin))
    span_rad = math.radians(80.0)
    assert half.value == pytest.approx(float(np.mean([e / (2 * span_rad) for e in per_trial])), rel=1e-6)
    assert slope.value == pytest.approx(0.2, abs=1e-3)  # the ellipse's cosine is orthogonal to the sine
    # a trial whose model diverged (NaN) is left out; one trial left has no interval
    diverged = loops[1][1] * np.nan
    (only, *_) = bouc_wen_functionals([loops[0], loops[1]], [loops[0][1], diverged])
    assert (
        only.value == pytest.approx(per_trial[0]) and math.isnan(only.ci95_low) and math.isnan(only.ci95_high)
    )


def test_each_interval_is_the_estimate_plus_minus_t_on_the_effective_dof_times_its_sigma() -> None:
    """The element fit's RMSE is sqrt(SSE / n); each parameter's 95 % interval is value +- t(0.975,
    n_eff - k) sqrt(C_jj) of the reported covariance (C already scaled for the residuals' correlation)."""
    comparison = compare_models(_trials(_device(), np.random.default_rng(6)), _device())
    fit = comparison.element_fit
    assert fit is not None
    assert fit.rmse_nm == math.sqrt(fit.sse / fit.n_samples)
    k = len(fit.estimates)
    q = stats.t.ppf(0.975, fit.n_eff - k)
    for j, estimate in enumerate(fit.estimates):
        half = q * math.sqrt(fit.covariance[j, j])
        assert estimate.ci95_high - estimate.value == pytest.approx(half, rel=1e-9)
        assert estimate.value - estimate.ci95_low == pytest.approx(half, rel=1e-9)
