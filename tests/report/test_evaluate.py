"""The generic evaluator (report/evaluate.py) on in-memory configurations whose trial means are set exactly:
each relation's decision rule, the numbers it prints and why a verdict is not evaluable."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.report.evaluate import evaluate_all, evaluate_expectation, metric_label
from protocol_runner.report.model import Configuration, ReportData, SessionInfo, Trial
from protocol_runner.report.settings_view import SettingsView


def cfg(key: int, trial_means: list[float]) -> Configuration:
    """A configuration whose trial t has one cycle of energy trial_means[t]."""
    trials = tuple(Trial(i + 1, None, None, None) for i in range(len(trial_means)))
    return Configuration(
        name=f"config_{key}",
        key=key,
        run=key,
        set_name="s",
        condition="",
        profile="sinusoid",
        status="complete",
        n_trials_planned=len(trials),
        settings=SettingsView(),
        trials=trials,
        energy_loss_j=np.asarray(trial_means, dtype=float),
        energy_cycle_trial=np.arange(1, len(trial_means) + 1, dtype=float),
        bouc_wen=None,
        element_fit=None,
        angle_min_deg=math.nan,
        angle_max_deg=math.nan,
        torque_slope_nm_per_deg=math.nan,
    )


def data(**configs: list[float]) -> ReportData:
    session = SessionInfo("a.h5", "p", "", 2, "", "dry-run", 0, "", "", "complete", "j", ())
    return ReportData(session, tuple(cfg(int(k[1:]), v) for k, v in configs.items()), (), ())


def spec(**fields: object) -> ExpectationSpec:
    return ExpectationSpec.model_validate({"id": "x", "text": "t", "metric": "energy_per_cycle", **fields})


RISING = data(c1=[1.0, 1.2, 1.1], c2=[2.0, 2.2, 2.1], c3=[3.0, 3.2, 3.1])


def test_increasing_is_met_when_every_step_rises_and_the_ends_differ() -> None:
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), RISING)
    assert (v.verdict, v.css, v.unit) == ("met", "met", "J")
    w = stats.ttest_ind([3.0, 3.2, 3.1], [1.0, 1.2, 1.1], equal_var=False).confidence_interval(0.95)
    assert v.reason == (
        f"means in order 1.10 < 2.10 < 3.10 J; configuration 3 minus 1: 2.00 J, 95 % Welch interval "
        f"[{w.low:.2f}, {w.high:.2f}] J"
    )
    assert [(e.key, e.n) for e in v.evidence] == [(1, 3), (2, 3), (3, 3)]
    assert v.evidence[0].mean == pytest.approx(1.1)
    lo, hi = stats.t.interval(0.95, 2, loc=1.1, scale=stats.sem([1.0, 1.2, 1.1]))
    assert (v.evidence[0].low, v.evidence[0].high) == (pytest.approx(lo), pytest.approx(hi))


def test_decreasing_in_the_reverse_order_and_a_wrong_direction() -> None:
    assert (
        evaluate_expectation(spec(relation="decreasing", configurations=[3, 2, 1]), RISING).verdict == "met"
    )
    v = evaluate_expectation(spec(relation="decreasing", configurations=[1, 2, 3]), RISING)
    assert v.verdict == "not met"
    assert "means in order 1.10 > 2.10 > 3.10 J" in v.reason
    assert v.reason.endswith("; not every step goes the stated way")


def test_a_rise_whose_ends_overlap_is_not_met() -> None:
    noisy = data(c1=[1.0, 3.0, 2.0], c2=[2.1, 2.2, 2.3], c3=[1.2, 3.4, 2.1])  # means 2.0 < 2.2 < 2.23
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), noisy)
    assert v.verdict == "not met"
    assert v.reason.endswith("; the interval does not exclude zero")


def test_no_trend_is_met_only_without_a_clear_trend() -> None:
    zigzag = data(c1=[1.0, 1.1], c2=[3.0, 3.1], c3=[2.0, 2.1])
    v = evaluate_expectation(spec(relation="no_trend", configurations=[1, 2, 3]), zigzag)
    assert v.verdict == "met"
    assert v.reason.endswith("; no step-by-step trend with an interval excluding zero")
    assert v.reason.startswith("means in order 1.05 < 3.05 < 2.05 J")
    for order in ([1, 2, 3], [3, 2, 1]):
        v = evaluate_expectation(spec(relation="no_trend", configurations=order), RISING)
        assert v.verdict == "not met" and v.reason.endswith("; a clear trend")


@pytest.mark.parametrize(
    ("relation", "extra", "verdict"),
    [
        ("greater", {}, "met"),
        ("less", {}, "not met"),
        ("equal", {"tolerance": 1.5}, "met"),
        ("equal", {"tolerance": 1.0}, "not met"),  # 1.0 +- ~0.25: the interval leaves +-1
    ],
)
def test_relations_between_configurations_use_the_welch_interval(
    relation: str, extra: dict[str, object], verdict: str
) -> None:
    v = evaluate_expectation(spec(relation=relation, configurations=[2], than=[1], **extra), RISING)
    assert v.verdict == verdict
    w = stats.ttest_ind([2.0, 2.2, 2.1], [1.0, 1.2, 1.1], equal_var=False).confidence_interval(0.95)
    assert v.reason.startswith(
        f"configuration 2 minus 1: 1.00 J, 95 % Welch interval [{w.low:.3g}, {w.high:.3g}] J"
    )
    assert ("(fails)" in v.reason) == (verdict == "not met")


def test_the_criterion_is_stated_after_the_numbers() -> None:
    cases = {
        "greater": (dict(than=[1]), " (must lie wholly above zero)"),
        "less": (dict(value=5.0), " (must lie wholly below 5 J)"),
        "equal": (dict(value=2.0, tolerance=0.5), " (must lie within 0.5 J of 2 J)"),
        "inside": (dict(interval=[1.5, 2.5]), " (must lie inside [1.5, 2.5] J)"),
    }
    for relation, (extra, text) in cases.items():
        v = evaluate_expectation(spec(relation=relation, configurations=[2], **extra), RISING)
        assert v.reason.endswith(text), (relation, v.reason)
        assert v.verdict == "met", relation
    v = evaluate_expectation(spec(relation="equal", configurations=[2], than=[1], tolerance=2.0), RISING)
    assert v.reason.endswith(" (must lie within 2 J of zero)")


@pytest.mark.parametrize(
    ("relation", "extra", "verdict"),
    [
        ("greater", {"value": 2.0}, "not met"),  # the interval [1.85, 2.35] reaches below 2
        ("greater", {"value": 1.8}, "met"),
        ("less", {"value": 2.5}, "met"),
        ("less", {"value": 2.2}, "not met"),
        ("equal", {"value": 2.1, "tolerance": 0.3}, "met"),
        ("equal", {"value": 2.1, "tolerance": 0.2}, "not met"),
        ("equal", {"value": 0.0, "tolerance": 3.0}, "met"),
        ("inside", {"interval": [1.8, 2.4]}, "met"),
        ("inside", {"interval": [1.9, 2.4]}, "not met"),
        ("inside", {"interval": [1.8, 2.3]}, "not met"),
    ],
)
def test_relations_against_a_value_use_the_t_interval(
    relation: str, extra: dict[str, object], verdict: str
) -> None:
    x = [2.0, 2.2, 2.1]
    lo, hi = stats.t.interval(0.95, 2, loc=np.mean(x), scale=stats.sem(x))  # [1.85, 2.35]
    v = evaluate_expectation(spec(relation=relation, configurations=[2], **extra), RISING)
    assert v.verdict == verdict, (v.reason, lo, hi)
    assert v.reason.startswith(f"configuration 2: mean 2.10 J, 95 % interval [{lo:.2f}, {hi:.2f}] J")


def test_every_pair_must_hold() -> None:
    both = spec(relation="greater", configurations=[2, 3], than=[1, 1])
    assert evaluate_expectation(both, RISING).verdict == "met"
    one_fails = spec(relation="greater", configurations=[2, 1], than=[1, 3])
    v = evaluate_expectation(one_fails, RISING)
    assert v.verdict == "not met"
    first, second = v.reason.split("; ")
    assert "(fails)" not in first and "(fails)" in second


def test_baselines_make_a_contrast() -> None:
    # what 3 adds over 1 (2.0) against what 2 adds over 1 (1.0), and against a value
    v = evaluate_expectation(
        spec(relation="greater", configurations=[3], baseline=[1], than=[2], than_baseline=[1]), RISING
    )
    assert v.verdict == "met" and v.reason.startswith("(3 minus 1) minus (2 minus 1): 1.00 J, 95 % Welch-Sat")
    v = evaluate_expectation(spec(relation="greater", configurations=[3], baseline=[1], than=[2]), RISING)
    assert v.reason.startswith("(3 minus 1) minus 2: -0.1 J, 95 % Welch-Satterthwaite interval")
    v = evaluate_expectation(spec(relation="less", configurations=[3], baseline=[1], value=2.5), RISING)
    assert v.verdict == "met" and v.reason.startswith("configuration 3 minus 1: 2.00 J, 95 % Welch interval")
    v = evaluate_expectation(
        spec(relation="greater", configurations=[3], than=[2], than_baseline=[1]), RISING
    )
    assert v.reason.startswith("(3) minus (2 minus 1): 2.10 J, 95 % Welch-Satterthwaite interval")


def test_missing_and_short_configurations_are_not_evaluable_with_the_reason() -> None:
    d = data(c1=[1.0, 1.2], c2=[2.0])
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 9]), d)
    assert v.verdict == "not evaluable" and v.css == "not-evaluable"
    assert v.reason == (
        "configuration 2 has 1 trial with energy per cycle; configuration 9 is not in this archive "
        "(the rule needs 2 per configuration)."
    )
    assert [(e.key, e.n) for e in v.evidence] == [(1, 2), (2, 1), (9, 0)]
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2], min_trials=3), RISING)
    assert v.verdict == "met"  # RISING has 3 trials each
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2], min_trials=4), RISING)
    assert v.verdict == "not evaluable"
    assert "configuration 1 has 3 trials with energy per cycle" in v.reason
    assert v.reason.endswith("(the rule needs 4 per configuration).")
    empty = data(c1=[], c2=[1.0, 2.0])
    v = evaluate_expectation(spec(relation="greater", configurations=[2], than=[1]), empty)
    assert v.reason.startswith("configuration 1 has no trials with energy per cycle")


def test_an_undefined_interval_never_meets_a_relation() -> None:
    d = data(c1=[1.0, 1.0], c2=[2.0, 2.0])  # no spread: zero-width intervals, still decided
    assert evaluate_expectation(spec(relation="greater", configurations=[2], than=[1]), d).verdict == "met"
    nan = data(c1=[1.0, math.nan], c2=[2.0, 2.1])
    v = evaluate_expectation(spec(relation="greater", configurations=[2], than=[1], min_trials=2), nan)
    assert v.verdict == "not evaluable"


def test_metric_labels_carry_their_argument() -> None:
    assert metric_label(spec(relation="inside", configurations=[1], interval=[0, 1])) == "energy per cycle"
    p = spec(metric="angle_percentile", percentile=99, relation="inside", configurations=[1], interval=[0, 1])
    assert metric_label(p) == "angle percentile 99"
    h = spec(
        metric="hysteresis_width", angle_deg=45.5, relation="inside", configurations=[1], interval=[0, 1]
    )
    assert metric_label(h) == "hysteresis width at 45.5°"


def test_numbers_are_printed_with_sensible_precision() -> None:
    small = data(c1=[0.01233, 0.01235])
    mid = data(c1=[12.341, 12.343])
    big = data(c1=[123.41, 123.43])
    inside = {"relation": "inside", "configurations": [1], "interval": [-1000, 1000]}
    assert "mean 0.0123 J" in evaluate_expectation(spec(**inside), small).reason
    assert "mean 12.34 J" in evaluate_expectation(spec(**inside), mid).reason
    assert "mean 123.4 J" in evaluate_expectation(spec(**inside), big).reason


def test_evaluate_all_keeps_the_declaration_order() -> None:
    specs = [
        spec(relation="increasing", configurations=[1, 2]).model_copy(update={"id": "b"}),
        spec(relation="decreasing", configurations=[1, 2]).model_copy(update={"id": "a"}),
    ]
    assert [(v.spec.id, v.verdict) for v in evaluate_all(specs, RISING)] == [("b", "met"), ("a", "not met")]


def test_a_fall_whose_ends_overlap_is_not_met() -> None:
    falling = data(c1=[3.1, 1.1, 2.1], c2=[2.0, 2.1, 1.9], c3=[1.0, 2.9, 1.9])  # means 2.1 > 2.0 > 1.93
    v = evaluate_expectation(spec(relation="decreasing", configurations=[1, 2, 3]), falling)
    assert v.verdict == "not met"
    assert v.reason.endswith("; the interval does not exclude zero")


def test_interval_bounds_are_inclusive() -> None:
    exact = data(c1=[2.0, 2.0, 2.0])  # zero-width interval at 2.0
    for interval in ([1.0, 2.0], [2.0, 3.0], [2.0, 2.0 + 1e-12]):
        assert (
            evaluate_expectation(
                spec(relation="inside", configurations=[1], interval=interval), exact
            ).verdict
            == "met"
        )
    for value in (1.5, 2.5):  # |2.0 - value| = 0.5 = tolerance: still equal
        v = evaluate_expectation(
            spec(relation="equal", configurations=[1], value=value, tolerance=0.5), exact
        )
        assert v.verdict == "met"
    assert (
        evaluate_expectation(
            spec(relation="inside", configurations=[1], interval=[2.0 + 1e-9, 3.0]), exact
        ).verdict
        == "not met"
    )


def test_a_plateau_is_not_a_trend() -> None:
    """A step whose means are equal goes neither way: with means 1, 1, 3 (ends far apart) the values do
    not increase at every step, and no_trend is then met although the ends differ."""
    plateau = data(c1=[0.9, 1.0, 1.1], c2=[0.9, 1.0, 1.1], c3=[2.9, 3.0, 3.1])
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), plateau)
    assert v.verdict == "not met" and v.reason.endswith("; not every step goes the stated way")
    v = evaluate_expectation(spec(relation="decreasing", configurations=[3, 2, 1]), plateau)
    assert v.verdict == "not met" and v.reason.endswith("; not every step goes the stated way")
    assert evaluate_expectation(spec(relation="no_trend", configurations=[1, 2, 3]), plateau).verdict == "met"


def test_from_one_unit_on_numbers_have_two_decimals() -> None:
    """Three significant digits below 1, two decimals from 1 up to 100 (1 itself included), one above."""
    inside = {"relation": "inside", "configurations": [1], "interval": [-1000, 1000]}
    for means, text in (
        ([99.99, 99.99], "mean 99.99 J"),
        ([100.0, 100.0], "mean 100.0 J"),
        ([1.0, 1.0], "mean 1.00 J"),
        ([0.5, 0.5], "mean 0.5 J"),
    ):
        assert text in evaluate_expectation(spec(**inside), data(c1=means)).reason, means


def test_an_interval_touching_the_reference_is_not_wholly_above_or_below_it() -> None:
    """`greater` / `less` need the interval wholly on one side: a zero-width interval at 2.0 is neither
    above nor below 2.0 (unlike `inside` and `equal`, whose bounds are inclusive)."""
    exact = data(c1=[2.0, 2.0, 2.0])
    for relation in ("greater", "less"):
        v = evaluate_expectation(spec(relation=relation, configurations=[1], value=2.0), exact)
        assert v.verdict == "not met", relation
    assert (
        evaluate_expectation(spec(relation="greater", configurations=[1], value=1.999), exact).verdict
        == "met"
    )
    assert (
        evaluate_expectation(spec(relation="less", configurations=[1], value=2.001), exact).verdict == "met"
    )
