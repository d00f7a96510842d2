"""Facts about the trial-level statistics (analysis/statistics.py), checked against scipy's own Student and
Welch tests and against one-way ANOVA worked by hand: the t-interval of a mean, the Welch interval,
degrees of freedom and p-value of a difference, a contrast of two groups being that difference, and the
intraclass correlation ICC(1) of balanced and unbalanced groups."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.analysis.statistics import (
    contrast_interval,
    p_above,
    p_below,
    repeatability,
    t_interval,
    trial_means,
    welch_interval,
)

A = [1.0, 2.0, 3.0, 4.0]
B = [2.0, 4.0, 6.0, 8.0, 10.0]


def test_the_t_interval_of_a_mean_is_students() -> None:
    values = [1.0, 2.0, 3.0, 4.0, 5.0]
    ci = t_interval(values)
    expected = stats.ttest_1samp(values, 0.0).confidence_interval(0.95)
    assert ci.n == 5 and ci.mean == pytest.approx(3.0) and ci.sd == pytest.approx(math.sqrt(2.5))
    assert (ci.low, ci.high) == pytest.approx((expected.low, expected.high), rel=1e-12)
    assert ci.half_width == pytest.approx((expected.high - expected.low) / 2.0, rel=1e-12)
    assert ci.cv == pytest.approx(math.sqrt(2.5) / 3.0)
    assert t_interval([-1.0, -2.0, -3.0]).cv == pytest.approx(1.0 / 2.0)  # sd / |mean|


def test_one_unit_has_a_mean_but_no_interval_or_cv() -> None:
    ci = t_interval([4.2, math.nan])
    assert ci.n == 1 and ci.mean == 4.2
    assert math.isnan(ci.low) and math.isnan(ci.high) and math.isnan(ci.cv)
    assert t_interval([]).n == 0 and math.isnan(t_interval([]).mean)
    assert math.isnan(t_interval([-1.0, 1.0]).cv)  # a zero mean has no relative spread


def test_trial_means_need_one_trial_id_per_value_however_many() -> None:
    values = np.arange(1000.0)
    numbers, means = trial_means(values, np.repeat([1, 2], 500))
    np.testing.assert_array_equal(numbers, [1, 2])
    np.testing.assert_allclose(means, [249.5, 749.5])
    with pytest.raises(ValueError, match="1000 values but 999 trial ids"):
        trial_means(values, np.ones(999, dtype=int))


@pytest.mark.parametrize(("a", "b"), [(A, B), (B, A), ([1.0, 3.0], [5.0, 9.0]), (A, [7.0, 11.0])])
def test_the_welch_interval_is_scipys_welch_test(a: list[float], b: list[float]) -> None:
    w = welch_interval(a, b)
    expected = stats.ttest_ind(b, a, equal_var=False)
    ci = expected.confidence_interval(0.95)
    assert w.difference == pytest.approx(np.mean(b) - np.mean(a), rel=1e-12)
    assert w.dof == pytest.approx(expected.df, rel=1e-12)
    assert w.p_value == pytest.approx(expected.pvalue, rel=1e-9)
    assert (w.low, w.high) == pytest.approx((ci.low, ci.high), rel=1e-9)
    # a contrast of the two groups with weights -1 and +1 is the same difference
    c = contrast_interval([(-1.0, a), (1.0, b)])
    assert (c.difference, c.low, c.high, c.dof, c.p_value) == pytest.approx(
        (w.difference, w.low, w.high, w.dof, w.p_value), rel=1e-12
    )


def test_a_one_group_contrast_is_the_student_interval_of_its_mean() -> None:
    c = contrast_interval([(1.0, B)])
    ci = t_interval(B)
    assert (c.difference, c.low, c.high, c.dof) == pytest.approx((ci.mean, ci.low, ci.high, len(B) - 1))
    assert c.p_value == pytest.approx(stats.ttest_1samp(B, 0.0).pvalue, rel=1e-9)


def test_constant_groups_give_a_zero_width_interval() -> None:
    same = welch_interval([2.0, 2.0], [2.0, 2.0, 2.0])
    assert (same.difference, same.low, same.high, same.p_value) == (0.0, 0.0, 0.0, 1.0)
    shifted = welch_interval([2.0, 2.0, 2.0], [5.0, 5.0])
    assert (shifted.difference, shifted.low, shifted.high, shifted.p_value) == (3.0, 3.0, 3.0, 0.0)
    assert shifted.dof == math.inf and shifted.significant
    flat = contrast_interval([(1.0, [2.0, 2.0]), (-1.0, [2.0, 2.0])])
    assert (flat.difference, flat.low, flat.high, flat.p_value) == (0.0, 0.0, 0.0, 1.0)


def test_a_group_of_one_unit_gives_a_difference_without_an_interval() -> None:
    cases = [
        (welch_interval([1.0], B), 5.0),  # mean(B) = 6
        (welch_interval(B, [1.0]), -5.0),
        (contrast_interval([(-1.0, [1.0]), (1.0, B)]), 5.0),
    ]
    for w, difference in cases:
        assert w.difference == pytest.approx(difference)
        assert math.isnan(w.low) and math.isnan(w.high) and not w.significant


def test_icc_of_balanced_groups_is_the_one_way_anova_ratio() -> None:
    """Groups (1, 2), (3, 4), (5, 6): MSB = 2 * ((-2)^2 + 0 + 2^2) / 2 = 8, MSW = 3 * 0.5 / 3 = 0.5, n0 = 2:
    ICC(1) = (8 - 0.5) / (8 + 0.5); between-group CV = sd(1.5, 3.5, 5.5) / 3.5 = 2 / 3.5."""
    r = repeatability([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    assert (r.groups, r.units, r.grand_mean) == (3, 6, 3.5)
    assert r.icc == pytest.approx(7.5 / 8.5, rel=1e-12)
    assert r.between_cv == pytest.approx(2.0 / 3.5, rel=1e-12)


def test_icc_of_unbalanced_groups_uses_the_effective_group_size() -> None:
    """Groups (1, 2, 3) and (7, 9): grand mean 22/5 = 4.4; SSB = 3 (2 - 4.4)^2 + 2 (8 - 4.4)^2 = 43.2,
    MSB = 43.2; SSW = 2 + 2 = 4, MSW = 4 / 3; n0 = (5 - 13/5) / 1 = 2.4."""
    r = repeatability([[1.0, 2.0, 3.0], [7.0, 9.0]])
    msb, msw, n0 = 43.2, 4.0 / 3.0, 2.4
    assert r.icc == pytest.approx((msb - msw) / (msb + (n0 - 1.0) * msw), rel=1e-12)
    assert r.between_cv == pytest.approx(np.std([2.0, 8.0], ddof=1) / 5.0, rel=1e-12)


def test_icc_needs_two_groups_and_replication() -> None:
    single_units = repeatability([[1.0], [3.0], [5.0]])
    assert single_units.groups == 3 and math.isnan(single_units.icc)
    assert single_units.between_cv == pytest.approx(2.0 / 3.0)
    one = repeatability([[1.0, 2.0, 3.0]])
    assert one.groups == 1 and math.isnan(one.icc) and math.isnan(one.between_cv)
    for nothing in ([], [[math.nan], []]):
        r = repeatability(nothing)
        assert (r.groups, r.units) == (0, 0) and math.isnan(r.grand_mean) and math.isnan(r.icc)


def test_a_contrast_estimate_carries_its_standard_error_and_one_sided_p_values() -> None:
    """The standard error behind an interval is s / sqrt(n) for one group's mean; "above ref" has the
    p-value P(T >= (estimate - ref) / se) of Student's t with n - 1 degrees of freedom, and "below ref" its
    complement; a weight of 2 doubles the estimate and its half width, not its degrees of freedom."""
    values = np.array([3.1, 2.4, 3.9, 3.3, 2.8, 3.6])
    n, mean, sd = values.size, float(values.mean()), float(values.std(ddof=1))
    single = contrast_interval([(1.0, values)])
    assert single.standard_error == pytest.approx(sd / math.sqrt(n), rel=1e-12)
    for ref in (0.0, 2.9, 3.5):
        t = (mean - ref) / (sd / math.sqrt(n))
        assert p_above(single, ref) == pytest.approx(float(stats.t.sf(t, n - 1)), rel=1e-9)
        assert p_below(single, ref) == pytest.approx(float(stats.t.cdf(t, n - 1)), rel=1e-9)
    doubled = contrast_interval([(2.0, values)])
    assert doubled.difference == pytest.approx(2.0 * mean, rel=1e-12)
    assert doubled.half_width == pytest.approx(2.0 * single.half_width, rel=1e-12)
    assert doubled.dof == pytest.approx(n - 1, rel=1e-12)


def test_without_spread_a_one_sided_statement_is_decided_by_the_difference_alone() -> None:
    same = welch_interval([2.0, 2.0, 2.0], [5.0, 5.0])  # difference 3, no spread
    assert p_above(same, 2.5) == 0.0 and p_below(same, 2.5) == 1.0
    assert p_above(same, 3.5) == 1.0 and p_below(same, 3.5) == 0.0


def test_a_group_without_two_values_has_a_difference_but_no_interval() -> None:
    one = welch_interval([1.0], [4.0, 6.0])
    assert one.difference == 4.0 and math.isnan(one.low) and math.isnan(one.high)
    empty = welch_interval([], [4.0, 6.0])
    assert math.isnan(empty.difference) and math.isnan(empty.low)


def test_a_negative_icc_is_shown_as_zero_with_a_note_and_a_positive_one_as_it_is() -> None:
    scattered = repeatability([[1.0, 3.0], [1.1, 2.9], [0.9, 3.1]])  # sets alike, trials apart
    assert scattered.icc < 0.0 and scattered.icc_shown == 0.0 and "shown as 0" in scattered.icc_note
    clustered = repeatability([[1.0, 1.1], [3.0, 3.1], [5.0, 4.9]])  # sets apart, trials alike
    assert clustered.icc > 0.9 and clustered.icc_shown == clustered.icc and clustered.icc_note == ""
