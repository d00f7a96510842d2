"""Trial-level statistics checked against scipy.stats on synthetic data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.analysis.statistics import (
    TInterval,
    coefficient_of_variation,
    contrast_interval,
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


@pytest.mark.parametrize("n", [2, 4, 9])
def test_a_contrast_of_one_group_is_its_t_interval(n: int) -> None:
    x = np.random.default_rng(40 + n).normal(3.0, 0.5, n)
    got = contrast_interval([(1.0, x)])
    low, high = stats.t.interval(0.95, n - 1, loc=x.mean(), scale=stats.sem(x))
    assert got.difference == pytest.approx(x.mean(), rel=1e-12)
    assert (got.low, got.high) == (pytest.approx(low, rel=1e-12), pytest.approx(high, rel=1e-12))
    assert got.dof == pytest.approx(n - 1, rel=1e-12)
    assert got.p_value == pytest.approx(stats.ttest_1samp(x, 0.0).pvalue, rel=1e-9)


@pytest.mark.parametrize(("na", "nb"), [(3, 3), (2, 6), (8, 3)])
def test_a_two_group_contrast_is_welchs_test(na: int, nb: int) -> None:
    rng = np.random.default_rng(na * 7 + nb)
    a, b = rng.normal(2.0, 0.3, na), rng.normal(2.4, 0.9, nb)
    got = contrast_interval([(-1.0, a), (1.0, b)])
    ref = stats.ttest_ind(b, a, equal_var=False)
    ci = ref.confidence_interval(0.95)
    assert got.low == pytest.approx(ci.low, rel=1e-9) and got.high == pytest.approx(ci.high, rel=1e-9)
    assert got.dof == pytest.approx(ref.df, rel=1e-12)
    assert got.p_value == pytest.approx(ref.pvalue, rel=1e-9)
    assert got == welch_interval(a, b)


def test_a_difference_of_differences_follows_the_welch_satterthwaite_formula() -> None:
    rng = np.random.default_rng(11)
    groups = [
        rng.normal(mu, sd, n) for mu, sd, n in ((7.0, 0.2, 3), (0.9, 0.05, 4), (7.8, 0.4, 3), (1.2, 0.1, 5))
    ]
    got = contrast_interval([(1.0, groups[0]), (-1.0, groups[1]), (-1.0, groups[2]), (1.0, groups[3])])
    value = groups[0].mean() - groups[1].mean() - groups[2].mean() + groups[3].mean()
    v = [g.var(ddof=1) / g.size for g in groups]  # weights are +-1: w^2 = 1
    dof = sum(v) ** 2 / sum(vi**2 / (g.size - 1) for vi, g in zip(v, groups, strict=True))
    half = stats.t.ppf(0.975, dof) * math.sqrt(sum(v))
    assert got.difference == pytest.approx(value, rel=1e-12)
    assert got.dof == pytest.approx(dof, rel=1e-12)
    assert (got.low, got.high) == (
        pytest.approx(value - half, rel=1e-12),
        pytest.approx(value + half, rel=1e-12),
    )
    assert got.p_value == pytest.approx(2 * stats.t.sf(abs(value) / math.sqrt(sum(v)), dof), rel=1e-9)


def test_a_difference_of_differences_covers_the_true_contrast_about_95_percent_of_the_time() -> None:
    rng = np.random.default_rng(12)
    truth = (5.0 - 1.0) - (6.0 - 2.0)  # zero: the added loss is the same
    hits = 0
    runs = 2000
    for _ in range(runs):
        a, b = rng.normal(5.0, 0.3, 3), rng.normal(1.0, 0.05, 3)
        c, d = rng.normal(6.0, 0.2, 4), rng.normal(2.0, 0.1, 3)
        got = contrast_interval([(1.0, a), (-1.0, b), (-1.0, c), (1.0, d)])
        hits += got.low <= truth <= got.high
    assert 0.93 <= hits / runs <= 0.975  # Welch-Satterthwaite is approximate, slightly conservative


def test_a_contrast_needs_two_units_per_group_and_data_in_every_group() -> None:
    short = contrast_interval([(1.0, [1.0, 2.0]), (-1.0, [0.5])])
    assert short.difference == pytest.approx(1.0) and math.isnan(short.low) and not short.significant
    assert math.isnan(contrast_interval([(1.0, [1.0, 2.0]), (-1.0, [])]).difference)
    assert math.isnan(contrast_interval([]).difference)
    exact = contrast_interval([(1.0, [2.0, 2.0]), (-1.0, [0.5, 0.5])])
    assert (exact.low, exact.high, exact.p_value) == (1.5, 1.5, 0.0)


def test_cv_is_undefined_at_a_zero_mean_and_defined_at_any_other() -> None:
    assert math.isnan(t_interval([-1.0, 1.0]).cv)  # mean exactly zero
    assert t_interval([0.5, 1.5]).cv == pytest.approx(np.std([0.5, 1.5], ddof=1) / 1.0)  # mean exactly 1
    assert t_interval([-1.5, -0.5]).cv == pytest.approx(np.std([0.5, 1.5], ddof=1) / 1.0)  # |mean|
    assert t_interval([2.0, 4.0]).cv == pytest.approx(math.sqrt(2.0) / 3.0)  # two units suffice


def test_constant_groups_give_an_exact_welch_difference() -> None:
    same = welch_interval([2.0, 2.0, 2.0], [2.0, 2.0])
    assert (same.difference, same.low, same.high, same.p_value) == (0.0, 0.0, 0.0, 1.0)
    assert same.dof == math.inf and not same.significant
    apart = welch_interval([2.0, 2.0], [3.5, 3.5])
    assert (apart.difference, apart.low, apart.high, apart.p_value) == (1.5, 1.5, 1.5, 0.0)
    assert apart.significant


def test_repeatability_of_one_group_and_of_none() -> None:
    one = repeatability([[1.0, 2.0]])
    assert (one.groups, one.units, one.grand_mean) == (1, 2, 1.5)
    assert math.isnan(one.between_cv) and math.isnan(one.icc)
    none = repeatability([[], [math.nan]])
    assert (none.groups, none.units) == (0, 0) and math.isnan(none.grand_mean)
    single_units = repeatability([[1.0], [2.0], [4.0]])  # no replication within a group: no ICC
    assert single_units.units == 3 and math.isnan(single_units.icc)
    assert single_units.between_cv == pytest.approx(np.std([1, 2, 4], ddof=1) / (7 / 3))


def test_a_single_unit_has_no_cv_whatever_its_spread_field_says() -> None:
    # the CV is a between-unit quantity: one unit has none, even if a caller fills `sd`
    assert math.isnan(TInterval(1, 2.0, 0.5, math.nan, math.nan).cv)
    assert TInterval(2, 2.0, 0.5, 1.0, 3.0).cv == 0.25
