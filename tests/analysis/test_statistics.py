"""Trial-level statistics checked against scipy.stats on synthetic data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.analysis.statistics import (
    coefficient_of_variation,
    repeatability,
    t_interval,
    trial_means,
    welch_interval,
)


def test_trial_means_average_cycles_within_each_trial() -> None:
    values = [1.0, 3.0, 10.0, 12.0, 14.0, math.nan]
    ids = [1, 1, 2, 2, 2, 3]
    numbers, means = trial_means(values, ids)
    assert numbers.tolist() == [1, 2]  # trial 3 has no finite cycle
    assert means.tolist() == [2.0, 12.0]


def test_trial_means_reject_mismatched_lengths() -> None:
    with pytest.raises(ValueError, match="3 values but 2 trial ids"):
        trial_means([1.0, 2.0, 3.0], [1, 2])


@pytest.mark.parametrize("n", [2, 3, 5, 12])
def test_t_interval_matches_scipy(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.normal(4.0, 0.7, n)
    got = t_interval(x)
    low, high = stats.t.interval(0.95, n - 1, loc=x.mean(), scale=stats.sem(x))
    assert got.n == n
    assert got.mean == pytest.approx(x.mean())
    assert got.low == pytest.approx(low, rel=1e-12)
    assert got.high == pytest.approx(high, rel=1e-12)
    assert got.cv == pytest.approx(np.std(x, ddof=1) / x.mean(), rel=1e-12)
    assert coefficient_of_variation(x) == pytest.approx(got.cv)


def test_t_interval_of_one_trial_has_no_interval() -> None:
    got = t_interval([2.5])
    assert got.mean == 2.5
    assert math.isnan(got.low) and math.isnan(got.high) and math.isnan(got.cv)


def test_pooling_cycles_would_understate_the_interval() -> None:
    # three trials whose cycles agree closely within each trial but differ between trials
    rng = np.random.default_rng(1)
    offsets = [0.0, 0.5, 1.0]
    cycles = np.concatenate([2.0 + o + rng.normal(0, 0.01, 20) for o in offsets])
    ids = np.repeat([1, 2, 3], 20)
    per_trial = t_interval(trial_means(cycles, ids)[1])
    pooled = stats.t.interval(0.95, cycles.size - 1, loc=cycles.mean(), scale=stats.sem(cycles))
    assert per_trial.half_width > 5 * (pooled[1] - pooled[0]) / 2


@pytest.mark.parametrize(("na", "nb"), [(3, 3), (3, 7), (10, 4)])
def test_welch_interval_matches_scipy(na: int, nb: int) -> None:
    rng = np.random.default_rng(na * 31 + nb)
    a = rng.normal(1.0, 0.2, na)
    b = rng.normal(1.5, 0.6, nb)
    got = welch_interval(a, b)
    ref = stats.ttest_ind(b, a, equal_var=False)
    ci = ref.confidence_interval(0.95)
    assert got.difference == pytest.approx(b.mean() - a.mean())
    assert got.low == pytest.approx(ci.low, rel=1e-9)
    assert got.high == pytest.approx(ci.high, rel=1e-9)
    assert got.dof == pytest.approx(ref.df, rel=1e-12)
    assert got.p_value == pytest.approx(ref.pvalue, rel=1e-9)
    assert got.significant == (ref.pvalue < 0.05)


def test_welch_interval_needs_two_trials_each() -> None:
    got = welch_interval([1.0], [2.0, 3.0])
    assert got.difference == pytest.approx(1.5)
    assert math.isnan(got.low) and not got.significant


def test_icc_of_balanced_groups_matches_one_way_anova() -> None:
    rng = np.random.default_rng(7)
    groups = [rng.normal(mu, 0.3, 3) for mu in (5.0, 5.4, 4.7, 5.1)]
    got = repeatability(groups)
    f = stats.f_oneway(*groups).statistic
    k = 3  # trials per group
    assert got.icc == pytest.approx((f - 1) / (f + k - 1), rel=1e-9)
    means = [g.mean() for g in groups]
    assert got.between_cv == pytest.approx(np.std(means, ddof=1) / np.mean(means), rel=1e-12)
    assert got.groups == 4 and got.units == 12


def test_icc_of_unbalanced_groups_uses_the_effective_group_size() -> None:
    rng = np.random.default_rng(8)
    groups = [rng.normal(mu, 0.2, n) for mu, n in ((1.0, 2), (1.6, 3), (0.7, 5))]
    got = repeatability(groups)
    f = stats.f_oneway(*groups).statistic
    sizes = np.array([2, 3, 5])
    n0 = (sizes.sum() - (sizes**2).sum() / sizes.sum()) / (len(sizes) - 1)
    assert got.icc == pytest.approx((f - 1) / (f + n0 - 1), rel=1e-9)


def test_identical_groups_are_perfectly_repeatable_and_one_group_is_undefined() -> None:
    same = repeatability([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]])
    assert same.between_cv == 0.0
    assert same.icc < 0.0  # no between-group variance at all: ICC(1) is negative, never near 1
    assert math.isnan(repeatability([[1.0, 2.0]]).icc)
