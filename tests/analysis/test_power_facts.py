"""Facts of the power of the report's tests (analysis/power.py): the textbook sample sizes of a two-sample t
test, the noncentral-t power against the tests actually run on simulated trials, and how the needed count
moves with the effect and the spread."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from protocol_runner.analysis.power import (
    Equivalence,
    OneSided,
    part_power,
    statement_power,
    trials_needed,
    welch_dof,
)


def _two_sided_power(effect_sd: float, n: int, alpha: float) -> float:
    """Two-sample Student t, equal n and SD 1, two-sided at `alpha`, from scipy's noncentral t directly."""
    dof = 2 * (n - 1)
    lam = effect_sd / math.sqrt(2.0 / n)
    crit = stats.t.ppf(1.0 - alpha / 2.0, dof)
    return float(stats.nct.sf(crit, dof, lam) + stats.nct.sf(crit, dof, -lam))


def test_a_5_percent_difference_at_a_5_percent_cv_needs_17_trials_per_configuration() -> None:
    # d = 0.05 / 0.05 = 1, two-sided 0.05, 80 %: the textbook 17 per group (Cohen 1988, Table 2.4.1)
    n = trials_needed([OneSided(0.05, (0.05, 0.05))], alpha=0.025)
    assert n == 17
    assert _two_sided_power(1.0, 16, 0.05) < 0.8 <= _two_sided_power(1.0, 17, 0.05)
    # the report's own test of a stated direction is one-sided at 0.05: 14 suffice for one expectation
    assert trials_needed([OneSided(0.05, (0.05, 0.05))], alpha=0.05) == 14


def test_welch_degrees_of_freedom() -> None:
    assert welch_dof((1.0, 1.0), 5) == pytest.approx(8.0)  # equal spread: Student's 2 (n - 1)
    assert welch_dof((2.0,), 5) == pytest.approx(4.0)  # one configuration: n - 1
    assert welch_dof((1.0, 0.0), 5) == pytest.approx(4.0)  # one spread dominates: its own n - 1
    assert 4.0 < welch_dof((1.0, 0.5), 5) < 8.0


def _simulated_rejections(rng: np.random.Generator, sds: tuple[float, float], effect: float, n: int) -> float:
    draws = 20000
    a = rng.normal(0.0, sds[0], size=(draws, n))
    b = rng.normal(effect, sds[1], size=(draws, n))
    p = stats.ttest_ind(b, a, axis=1, equal_var=False, alternative="greater").pvalue
    return float(np.mean(p <= 0.05))


@pytest.mark.parametrize(
    ("sds", "effect", "n"), [((1.0, 1.0), 1.2, 10), ((0.5, 1.5), 1.0, 12), ((1.0, 0.2), 0.6, 15)]
)
def test_the_one_sided_welch_power_is_the_rate_at_which_welchs_test_rejects(
    sds: tuple[float, float], effect: float, n: int
) -> None:
    rate = _simulated_rejections(np.random.default_rng(11), sds, effect, n)
    assert part_power(OneSided(effect, sds), n, 0.05) == pytest.approx(rate, abs=0.02)


def test_with_few_trials_welchs_test_has_less_power_than_computed() -> None:
    # its degrees of freedom are estimated from the trials and lower than the planning SDs' Satterthwaite
    # value: the computed count of a few trials is the least that could decide (module docstring)
    rate = _simulated_rejections(np.random.default_rng(3), (1.0, 1.0), 1.5, 4)
    computed = part_power(OneSided(1.5, (1.0, 1.0)), 4, 0.05)
    assert rate < computed - 0.01
    assert rate > computed - 0.1


def test_the_tost_power_is_a_lower_bound_close_to_the_rate_at_which_tost_decides() -> None:
    rng = np.random.default_rng(5)
    margin, sd, draws = 1.0, 1.0, 20000
    for n in (6, 12, 20):
        a = rng.normal(0.0, sd, size=(draws, n))
        b = rng.normal(0.0, sd, size=(draws, n))
        diff = b.mean(axis=1) - a.mean(axis=1)
        se = np.sqrt(a.var(axis=1, ddof=1) / n + b.var(axis=1, ddof=1) / n)
        dof = se**4 / (
            (a.var(axis=1, ddof=1) / n) ** 2 / (n - 1) + (b.var(axis=1, ddof=1) / n) ** 2 / (n - 1)
        )
        crit = stats.t.ppf(0.95, dof)
        rate = float(np.mean((diff - crit * se > -margin) & (diff + crit * se < margin)))
        bound = part_power(Equivalence(0.0, -margin, margin, (sd, sd)), n, 0.05)
        assert bound <= rate + 0.01
        if rate > 0.7:
            assert bound == pytest.approx(rate, abs=0.03)


def test_a_statement_of_several_parts_has_at_most_the_power_of_its_weakest_part() -> None:
    parts = [OneSided(1.0, (1.0, 1.0)), OneSided(2.0, (1.0, 1.0))]
    each = [part_power(p, 8, 0.01) for p in parts]
    both = statement_power(parts, 8, 0.01)
    assert both == pytest.approx(1.0 - sum(1.0 - p for p in each))
    assert both <= min(each)
    needed = trials_needed(parts, 0.01)
    assert needed is not None and needed >= trials_needed(parts[:1], 0.01)  # type: ignore[operator]


def test_a_true_value_outside_the_interval_gives_no_power_and_no_count() -> None:
    part = Equivalence(2.0, -1.0, 1.0, (1.0,))
    assert part_power(part, 50, 0.05) == 0.0
    assert trials_needed([part], 0.05) is None


def test_no_spread_decides_with_the_least_trials() -> None:
    assert trials_needed([OneSided(0.1, (0.0, 0.0))], 0.001, least=3) == 3


def _needed(part: OneSided | Equivalence, alpha: float) -> int:
    n = trials_needed([part], alpha, most=5000)
    return 5001 if n is None else n


@settings(max_examples=40, deadline=None)
@given(
    effect=st.floats(0.2, 3.0),
    grow=st.floats(1.1, 3.0),
    sd=st.floats(0.2, 3.0),
    alpha=st.sampled_from([0.05, 0.01, 0.0028]),
)
def test_the_needed_count_falls_as_the_effect_grows_and_rises_with_the_spread(
    effect: float, grow: float, sd: float, alpha: float
) -> None:
    base = _needed(OneSided(effect, (sd, sd)), alpha)
    assert _needed(OneSided(effect * grow, (sd, sd)), alpha) <= base
    assert _needed(OneSided(effect, (sd * grow, sd)), alpha) >= base
    # an equivalence: a wider margin needs fewer trials, more spread more
    tost = _needed(Equivalence(0.0, -effect, effect, (sd, sd)), alpha)
    assert _needed(Equivalence(0.0, -effect * grow, effect * grow, (sd, sd)), alpha) <= tost
    assert _needed(Equivalence(0.0, -effect, effect, (sd, sd * grow)), alpha) >= tost


def test_welch_degrees_of_freedom_exactly() -> None:
    """(n - 1) (sum v_i)^2 / sum v_i^2 with v_i = s_i^2, to the last digits; no spread at all: n - 1."""
    assert welch_dof((1.0, 0.5), 5) == pytest.approx(4 * 1.25**2 / 1.0625, rel=1e-12)  # 5.88..., not 5
    assert welch_dof((0.0, 0.0), 5) == 4.0


def test_without_spread_the_sign_of_the_effect_decides() -> None:
    assert part_power(OneSided(0.1, (0.0, 0.0)), 4, 0.05) == 1.0
    assert part_power(OneSided(-0.1, (0.0, 0.0)), 4, 0.05) == 0.0


def test_two_trials_are_the_fewest_a_power_is_computed_for() -> None:
    assert 0.0 < part_power(OneSided(1.0, (1.0, 1.0)), 2, 0.05) < 1.0
    with pytest.raises(ValueError, match="two trials"):
        part_power(OneSided(1.0, (1.0, 1.0)), 1, 0.05)


@pytest.mark.parametrize("true_value", [-2.0, -1.02, -1.0, 1.0, 1.02, 2.0])
def test_a_true_value_on_or_beyond_either_bound_gives_no_power(true_value: float) -> None:
    """Not the Bonferroni bound, which is a little above 0 just beyond a bound (-1.02, 1.02): a statement
    that is false is decided only at the test's size, and a plan cannot count on that."""
    assert part_power(Equivalence(true_value, -1.0, 1.0, (0.3,)), 50, 0.05) == 0.0


@pytest.mark.parametrize("effect", [0.37, 0.5, 0.81, 1.3])
def test_the_count_is_a_whole_number_of_trials_the_fewest_with_the_power(effect: float) -> None:
    part = OneSided(effect, (1.0, 0.7))
    n = trials_needed([part], 0.05)
    assert isinstance(n, int)
    assert part_power(part, n, 0.05) >= 0.8 > part_power(part, n - 1, 0.05)


def test_a_statement_of_several_weak_parts_has_no_power_not_a_negative_one() -> None:
    parts = [OneSided(0.3, (1.0, 1.0))] * 3  # each about a fifth at 4 trials: 1 - sum(1 - p_i) < 0
    assert 0.0 < part_power(parts[0], 4, 0.05) < 0.5
    assert statement_power(parts, 4, 0.05) == 0.0
