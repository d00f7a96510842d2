"""Facts of the parameter intervals (models/bouc_wen/identifiability.py): the chi-square threshold, the AR(1)
effective sample size of correlated residuals, the profile's crossing of its threshold, Wald intervals
symmetric about the estimate, and n's interval inside n's bounds."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from protocol_runner.models.bouc_wen import identifiability as ident
from protocol_runner.models.bouc_wen.fitting import fit_trials
from protocol_runner.models.bouc_wen.identifiability import (
    CHI2_1_95,
    _crossing,
    effective_samples,
    identify,
    weak_reasons,
)
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import FitScale, Problem, Samples
from protocol_runner.models.bouc_wen.records import BoucWenBounds, BoucWenFit
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
PERIOD_S = 8.17


def test_the_threshold_is_the_95_percent_quantile_of_chi_square_with_one_degree_of_freedom() -> None:
    assert float(chi2.ppf(0.95, 1)) == pytest.approx(CHI2_1_95, rel=1e-12)


def _seg(*lengths: int) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)


def test_an_ar1_series_has_the_ar1_effective_sample_size() -> None:
    """Residuals r_i = phi r_{i-1} + e_i (phi = 0.8) carry m (1 - phi) / (1 + phi) = m / 9 independent
    errors; white noise carries m."""
    rng = np.random.default_rng(4)
    m = 40_000
    e = rng.standard_normal(m)
    r = np.empty(m)
    r[0] = e[0]
    for i in range(1, m):
        r[i] = 0.8 * r[i - 1] + e[i]
    assert effective_samples(r, _seg(m)) == pytest.approx(m / 9.0, rel=0.05)
    assert effective_samples(e, _seg(m)) == pytest.approx(m, rel=0.02)


def test_each_trial_is_centred_on_its_own_mean_and_every_trial_counts() -> None:
    """Two trials of white noise about different offsets (+5 and -5): about each trial's own mean they are
    uncorrelated, m_eff = m.  A smooth (correlated) second trial lowers m_eff."""
    rng = np.random.default_rng(8)
    m = 5000
    white = np.concatenate([5.0 + rng.standard_normal(m), -5.0 + rng.standard_normal(m)])
    assert effective_samples(white, _seg(m, m)) == pytest.approx(2 * m, rel=0.05)
    smooth = np.concatenate([rng.standard_normal(m), np.sin(np.linspace(0.0, 20.0, m))])
    assert effective_samples(smooth, _seg(m, m)) < 0.6 * 2 * m


def test_residuals_without_correlation_information_keep_every_sample_and_at_least_two() -> None:
    """All-zero residuals show no correlation (m_eff = m); residuals as smooth as a ramp count as at least
    2 independent errors (rho is capped just below 1)."""
    assert effective_samples(np.zeros(50), _seg(50)) == 50.0
    assert effective_samples(np.linspace(-1.0, 1.0, 1000), _seg(1000)) == 2.0
    alternating = np.tile([1.0, -1.0], 50)  # negative correlation counts as none
    assert effective_samples(alternating, _seg(100)) == 100.0


def test_the_crossing_of_a_quadratic_profile_is_exact() -> None:
    """SSE(n) = 10 + 4 (n - 1)^2 crosses the limit 14 at n = 2: from any point inside and one outside."""
    sse0, limit = 10.0, 14.0

    def sse(n: float) -> float:
        return sse0 + 4.0 * (n - 1.0) ** 2

    assert _crossing(1.2, sse(1.2), 2.6, sse(2.6), sse0, limit) == pytest.approx(2.0, rel=1e-12)
    assert _crossing(1.0, sse(1.0), 3.0, sse(3.0), sse0, limit) == pytest.approx(2.0, rel=1e-12)
    assert _crossing(0.8, sse(0.8), -0.5, sse(-0.5), sse0, limit) == pytest.approx(0.0, abs=1e-12)
    # a profile that does not rise between the two points: the outer point is the end
    assert _crossing(1.5, 12.0, 2.5, 11.0, sse0, limit) == 2.5
    assert _crossing(1.5, 12.0, 2.5, 12.0, sse0, limit) == 2.5


def _problem() -> Problem:
    x = np.linspace(-1.0, 1.0, 20)
    return Problem(Samples(x, x.copy(), _seg(x.size)), BoucWenBounds(), FitScale(1.0, 1.0))


def test_every_undetermined_parameter_is_named_not_only_the_first() -> None:
    problem = _problem()
    u = np.array([10.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    std = np.full(8, 1e-3)
    std[2] = math.inf
    std[7] = 60.0  # psi'6: +-118 of a -100..100 range
    reasons = weak_reasons(u, std, (0.9, 1.1), problem)
    assert len(reasons) == 2
    assert reasons[0].startswith("psi'1") and "not determined" in reasons[0]
    assert reasons[1].startswith("psi'6") and "covers 100 %" in reasons[1]


def _rich_loops() -> list[tuple[np.ndarray, np.ndarray]]:
    t = np.arange(0.0, 2 * PERIOD_S, 1.0 / 25.0)
    x = 60.0 * np.sin(2.0 * np.pi * t / PERIOD_S)
    rng = np.random.default_rng(5)
    return [(x, simulate(x, FIG57, 0.0) + 0.05 * rng.standard_normal(x.size)) for _ in range(2)]


@pytest.fixture(scope="module")
def identified() -> tuple[BoucWenFit, BoucWenFit]:
    segments = _rich_loops()
    fitted = fit_trials(segments, starts=1)
    # a result whose scheme name was read back (a new string object, as from an archive)
    read_back = replace(fitted, scheme="".join(list(fitted.scheme)))
    return identify(segments, fitted), identify(segments, read_back)


def test_wald_intervals_are_symmetric_about_the_estimate_and_n_stays_within_its_bounds(
    identified: tuple[BoucWenFit, BoucWenFit],
) -> None:
    result, _ = identified
    theta = result.params.as_array()
    low, high = np.array(result.param_interval_low), np.array(result.param_interval_high)
    for k in (0, *range(2, 8)):
        assert low[k] < theta[k] < high[k]
        assert high[k] - theta[k] == pytest.approx(theta[k] - low[k], rel=1e-9)
    n_lo, n_hi = result.n_interval
    assert (low[1], high[1]) == (n_lo, n_hi)
    assert result.bounds.n_min <= n_lo < theta[1] < n_hi <= result.bounds.n_max


def test_the_intervals_do_not_depend_on_how_the_scheme_name_was_obtained(
    identified: tuple[BoucWenFit, BoucWenFit],
) -> None:
    direct, read_back = identified
    assert read_back.n_interval == direct.n_interval
    assert read_back.param_interval_low == direct.param_interval_low
    assert read_back.param_interval_high == direct.param_interval_high


def test_a_flat_profile_leaves_n_open_from_bound_to_bound() -> None:
    """Torque proportional to the angle (an ideal spring, no hysteresis): nothing bends, so n's exponent
    changes nothing the data show; its profile stays below the threshold out to both bounds and the
    interval is n's whole range [n_min, n_max]."""
    t = np.arange(0.0, 2 * PERIOD_S, 1.0 / 25.0)
    x = 60.0 * np.sin(2.0 * np.pi * t / PERIOD_S)
    rng = np.random.default_rng(2)
    segments = [(x, 0.3 * x + 0.05 * rng.standard_normal(x.size)) for _ in range(2)]
    result = identify(segments, fit_trials(segments, starts=1))
    assert result.n_interval == (result.bounds.n_min, result.bounds.n_max)
    assert any(r.startswith("n:") for r in result.weak_reasons)


def test_a_trial_of_400_samples_is_profiled_on_every_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """The profile runs on a copy of at most 400 samples per trial (the module notes): a trial of exactly
    400 is not decimated, so its intervals are those of a profile on every sample (any larger limit)."""
    from protocol_runner.models.bouc_wen import identifiability

    x = 60.0 * np.sin(2.0 * np.pi * np.arange(400) / 200.0)
    rng = np.random.default_rng(9)
    segments = [(x, simulate(x, FIG57, 0.0) + 0.05 * rng.standard_normal(x.size))]
    fitted = fit_trials(segments, starts=0)
    default = identify(segments, fitted)
    monkeypatch.setattr(identifiability, "PROFILE_SAMPLES", 10**6)
    every = identify(segments, fitted)
    assert default.n_interval == every.n_interval
    assert default.param_interval_low == every.param_interval_low


def test_a_bound_inside_the_interval_ends_it_there(identified: tuple[BoucWenFit, BoucWenFit]) -> None:
    """n_max moved to 70 % of the way from the fitted n to the upper end of its interval: the data allow
    every n up to the bound, so the interval ends exactly at the bound, never beyond it."""
    result, _ = identified
    n_best, upper = result.params.n, result.n_interval[1]
    n_max = n_best + 0.7 * (upper - n_best)
    segments = _rich_loops()
    bounded = identify(segments, fit_trials(segments, starts=1, bounds=BoucWenBounds(n_max=n_max)))
    assert bounded.n_interval[1] == n_max
    assert bounded.n_interval[0] == pytest.approx(result.n_interval[0], rel=1e-6)


def test_an_interval_covering_exactly_half_the_range_is_not_weak() -> None:
    """Weak means covering *more* than half of the plausible range: n's range is 0.5-3, so an interval of
    1.0-2.25 (exactly half) is not weak and 1.0-2.26 is."""
    problem = _problem()
    u = np.array([10.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    narrow = np.full(8, 1e-3)
    assert weak_reasons(u, narrow, (1.0, 2.25), problem) == []
    assert [r[:2] for r in weak_reasons(u, narrow, (1.0, 2.26), problem)] == ["n:"]


def test_the_n_profile_steps_from_the_estimate_toward_each_bound_and_stays_within_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The profile likelihood of n (§6.2.3 intervals) refits at fixed n on a walk from the estimate out to
    each bound (the lower one first): every fixed n lies within the bounds, and the walks go both ways."""
    from protocol_runner.models.bouc_wen import identifiability as ident

    fixed: list[float] = []
    refit = ident._fixed_n_refit

    def recording(problem: Problem, u0: np.ndarray, max_nfev: int | None = None) -> tuple[np.ndarray, float]:
        fixed.append(float(u0[1]))
        return refit(problem, u0, max_nfev)

    monkeypatch.setattr(ident, "_fixed_n_refit", recording)
    segments = _rich_loops()
    fitted = fit_trials(segments, starts=1)
    result = identify(segments, fitted)
    n_hat, bounds = fitted.params.n, result.bounds
    assert fixed
    assert all(bounds.n_min <= n <= bounds.n_max for n in fixed)
    assert any(n < n_hat for n in fixed) and any(n > n_hat for n in fixed)
    assert fixed[0] < n_hat  # the first walk goes toward the lower bound


def _profile_of(monkeypatch: pytest.MonkeyPatch, sse_at_n) -> None:  # type: ignore[no-untyped-def]
    """Replace the fixed-n refits by a given profile SSE(n) (the refit's point is its start)."""
    from protocol_runner.models.bouc_wen import identifiability as ident

    monkeypatch.setattr(
        ident, "_fixed_n_refit", lambda problem, u0, max_nfev=None: (u0, float(sse_at_n(float(u0[1]))))
    )


def test_a_quadratic_profile_gives_the_likelihood_ratio_interval_exactly(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SSE(n) = SSE_min (1 + (n - n_hat)^2): the 95 % interval is where SSE = SSE_min exp(chi2_1,95 / m_eff),
    n_hat -+ sqrt(exp(chi2 / m_eff) - 1)."""
    from types import SimpleNamespace

    from protocol_runner.models.bouc_wen.identifiability import _n_profile

    sse0, m_eff, n_hat = 100.0, 50.0, 1.5
    _profile_of(monkeypatch, lambda n: sse0 * (1.0 + (n - n_hat) ** 2))
    problem = SimpleNamespace(bounds=BoucWenBounds())
    u = np.zeros(8)
    u[1] = n_hat
    low, high = _n_profile(problem, u, sse0, m_eff)  # type: ignore[arg-type]
    half = math.sqrt(math.exp(CHI2_1_95 / m_eff) - 1.0)
    assert low == pytest.approx(n_hat - half, rel=1e-12)
    assert high == pytest.approx(n_hat + half, rel=1e-12)


def test_a_better_optimum_met_on_the_profile_becomes_its_minimum(monkeypatch: pytest.MonkeyPatch) -> None:
    """The profile's first fixed-n refit toward the lower bound finds a lower SSE than the fit's: the
    interval is measured from that minimum (quadratic about it: its lower end is exact)."""
    from types import SimpleNamespace

    from protocol_runner.models.bouc_wen.identifiability import PROFILE_STEPS, _n_profile

    bounds = BoucWenBounds()
    m_eff, n_hat = 50.0, 1.5
    n_star = n_hat + float(PROFILE_STEPS[0]) * (bounds.n_min - n_hat)  # the first point of the walk
    s_min = 90.0
    _profile_of(monkeypatch, lambda n: s_min * (1.0 + (n - n_star) ** 2))
    sse_fit = s_min * (1.0 + (n_hat - n_star) ** 2) + 5.0  # the fit stopped above the profile's minimum
    u = np.zeros(8)
    u[1] = n_hat
    low, high = _n_profile(SimpleNamespace(bounds=bounds), u, sse_fit, m_eff)  # type: ignore[arg-type]
    half = math.sqrt(math.exp(CHI2_1_95 / m_eff) - 1.0)
    assert low == pytest.approx(n_star - half, rel=1e-12)
    assert high > n_hat


def test_correlated_residuals_widen_every_interval_by_the_square_root_of_n_over_the_effective_n(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """n residuals worth m_eff independent ones carry m_eff samples' information: each parameter's sigma,
    and so its Wald interval, is sqrt(n / m_eff) times what independent errors give; with the data worth
    a ten-thousandth of their number, parameters besides n (whose profile interval is its own) are weak."""
    segments = _rich_loops()
    fitted = fit_trials(segments, starts=1)

    def worth(share: float) -> BoucWenFit:
        monkeypatch.setattr(ident, "effective_samples", lambda r, seg: r.size * share)
        return identify(segments, fitted)

    independent, quarter, little = worth(1.0), worth(0.25), worth(1e-4)
    theta = fitted.params.as_array()
    for k in (0, *range(2, 8)):
        assert quarter.param_std[k] == pytest.approx(2.0 * independent.param_std[k], rel=1e-9)
        width = quarter.param_interval_high[k] - theta[k]
        assert width == pytest.approx(1.96 * 2.0 * independent.param_std[k], rel=1e-9)
    assert not independent.weakly_identified, independent.weak_reasons
    assert any(not reason.startswith("n:") for reason in little.weak_reasons), little.weak_reasons
