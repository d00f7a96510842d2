"""The generic evaluator (report/evaluate.py) on in-memory configurations whose trial means are set exactly:
each relation's decision rule, the numbers it prints and why a verdict is not evaluable."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.report.evaluate import Verdict, evaluate_all, format_p, metric_label
from protocol_runner.report.model import Configuration, ReportData, SessionInfo, Trial
from protocol_runner.report.settings_view import DeviceElement, SettingsView


def evaluate_expectation(spec: ExpectationSpec, data: ReportData) -> Verdict:
    """`spec` decided on `data` alone (a single-joint archive: a family of one)."""
    return evaluate_all([spec], data)[0]


def cfg(key: int, trial_means: list[float]) -> Configuration:
    """A configuration whose trial t has one cycle of energy trial_means[t]."""
    trials = tuple(Trial(i + 1, None, None, None) for i in range(len(trial_means)))
    return Configuration(
        name=f"config_{key}",
        key=key,
        joint="j",
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
    )


def data(**configs: list[float]) -> ReportData:
    session = SessionInfo("a.h5", "p", "", 2, "", "dry-run", 0, "", "", "complete", "j", ())
    return ReportData(session, tuple(cfg(int(k[1:]), v) for k, v in configs.items()), (), ())


def spec(**fields: object) -> ExpectationSpec:
    return ExpectationSpec.model_validate({"id": "x", "text": "t", "metric": "energy_per_cycle", **fields})


def p_greater(b: list[float], a: list[float], shift: float = 0.0) -> float:
    """scipy's one-sided Welch p-value of mean(b) - mean(a) > shift."""
    return float(stats.ttest_ind(np.asarray(b) - shift, a, equal_var=False, alternative="greater").pvalue)


def welch90(b: list[float], a: list[float]) -> tuple[float, float]:
    ci = stats.ttest_ind(b, a, equal_var=False).confidence_interval(0.90)
    return float(ci.low), float(ci.high)


RISING = data(c1=[1.0, 1.2, 1.1], c2=[2.0, 2.2, 2.1], c3=[3.0, 3.2, 3.1])


def test_increasing_is_met_when_every_adjacent_step_rises_significantly() -> None:
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), RISING)
    assert (v.verdict, v.unit) == ("met", "J")
    lo, hi = welch90([2.0, 2.2, 2.1], [1.0, 1.2, 1.1])
    assert v.reason.startswith(
        f"means in the stated order (1, 2, 3): 1.10 < 2.10 < 3.10 J; 2 minus 1: 1.00 J, 90 % Welch interval "
        f"[{lo:.3g}, {hi:.2f}] J, one-sided p < 0.001; 3 minus 2: 1.00 J"
    )
    steps = [p_greater([2.0, 2.2, 2.1], [1.0, 1.2, 1.1]), p_greater([3.0, 3.2, 3.1], [2.0, 2.2, 2.1])]
    assert v.p_value == pytest.approx(max(steps))  # the conjunction of the steps: the largest p decides
    assert (v.p_adjusted, v.family) == (v.p_value, 1)
    assert [(e.key, e.n) for e in v.evidence] == [(1, 3), (2, 3), (3, 3)]
    ci = stats.t.interval(0.95, 2, loc=1.1, scale=stats.sem([1.0, 1.2, 1.1]))
    assert (v.evidence[0].low, v.evidence[0].high) == (pytest.approx(ci[0]), pytest.approx(ci[1]))


def test_a_flat_middle_step_fails_increasing_although_the_ends_differ() -> None:
    """Means 1, 1, 3: the first and last configurations differ hugely, but the stated order says every
    step rises, and 2 minus 1 does not: not met, that step marked."""
    plateau = data(c1=[0.9, 1.0, 1.1], c2=[0.9, 1.0, 1.1], c3=[2.9, 3.0, 3.1])
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), plateau)
    assert v.verdict == "not met"
    assert "1.00 = 1.00 < 3.00 J" in v.reason
    assert "2 minus 1: 0 J" in v.reason and "one-sided p 0.5 (fails)" in v.reason
    assert v.p_value == pytest.approx(0.5)
    v = evaluate_expectation(spec(relation="decreasing", configurations=[3, 2, 1]), plateau)
    assert v.verdict == "not met" and "3.00 > 1.00 = 1.00 J" in v.reason


def test_the_evidence_orders_values_with_the_sign_the_data_show() -> None:
    """A decreasing statement on falling means prints "20.15 > 16.74 > 11.85", and on rising means the
    true signs (never the stated relation's sign between values that go the other way)."""
    falling = data(c1=[20.1, 20.2, 20.15], c2=[16.7, 16.78, 16.74], c3=[11.8, 11.9, 11.85])
    v = evaluate_expectation(spec(relation="decreasing", configurations=[1, 2, 3]), falling)
    assert v.verdict == "met"
    assert v.reason.startswith("means in the stated order (1, 2, 3): 20.15 > 16.74 > 11.85 J")
    assert "(every step must lie below zero, one-sided Welch; the largest step p decides)" in v.reason
    v = evaluate_expectation(spec(relation="decreasing", configurations=[1, 2, 3]), RISING)
    assert v.verdict == "not met" and "1.10 < 2.10 < 3.10 J" in v.reason
    assert v.reason.count("(fails)") == 2


def test_a_rise_within_the_noise_is_not_met() -> None:
    noisy = data(c1=[1.0, 3.0, 2.0], c2=[2.1, 2.2, 2.3], c3=[1.2, 3.4, 2.1])  # means 2.0 < 2.2 < 2.23
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 3]), noisy)
    assert v.verdict == "not met"
    assert v.p_value == pytest.approx(
        max(p_greater([2.1, 2.2, 2.3], [1.0, 3.0, 2.0]), p_greater([1.2, 3.4, 2.1], [2.1, 2.2, 2.3]))
    )


def spread(centre: float, n: int) -> list[float]:
    """n trial values around `centre`: the pattern -1, 0, +1 repeated (sample sd about 0.8-1)."""
    return [centre + (-1.0, 0.0, 1.0)[i % 3] for i in range(n)]


def test_two_equal_groups_pass_equal_only_with_enough_trials_for_the_margin() -> None:
    """Equal is an equivalence test (TOST): the same means with 3 trials each cannot show that the
    difference lies within ±1 (the 90 % interval is about ±1.7); with 30 each they can."""
    equal = {"relation": "equal", "configurations": [2], "than": [1], "margin": 1.0}
    few = evaluate_expectation(spec(**equal), data(c1=spread(5.0, 3), c2=spread(5.0, 3)))
    assert few.verdict == "not met" and "TOST p" in few.reason and "(fails)" in few.reason
    many = evaluate_expectation(spec(**equal), data(c1=spread(5.0, 30), c2=spread(5.0, 30)))
    assert many.verdict == "met"
    a, b = spread(5.0, 30), spread(5.0, 30)
    tost = max(p_greater(b, a, -1.0), p_greater(a, b, -1.0))  # above -1 and below +1
    assert many.p_value == pytest.approx(tost)
    assert many.reason.endswith("(a family of one, not adjusted): met at 0.05")
    assert "(the 90 % interval must lie within ±1 J of zero: TOST)" in many.reason


def test_equal_needs_a_margin_and_accepts_tolerance_as_its_older_name() -> None:
    with pytest.raises(ValueError, match="needs `margin`"):
        spec(relation="equal", configurations=[2], than=[1])
    with pytest.raises(ValueError, match="needs `margin`"):
        spec(relation="no_trend", configurations=[1, 2])
    assert spec(relation="equal", configurations=[2], than=[1], tolerance=0.5).margin == 0.5
    with pytest.raises(ValueError, match="takes no `margin`"):
        spec(relation="greater", configurations=[2], than=[1], margin=0.5)


def test_no_trend_needs_evidence_of_flatness_not_an_absence_of_evidence() -> None:
    """Three noisy configurations with 3 trials: nothing is significant, yet no_trend is NOT met (their
    intervals are wider than the margin). With 30 trials each, flat within ±1: met. A zigzag whose pairs
    differ by 2 is not met either."""
    no_trend = {"relation": "no_trend", "configurations": [1, 2, 3], "margin": 1.0}
    few = data(c1=spread(5.0, 3), c2=spread(5.2, 3), c3=spread(4.9, 3))
    v = evaluate_expectation(spec(**no_trend), few)
    assert v.verdict == "not met"
    assert v.reason.count("TOST p") == 3  # every pair: 2-1, 3-1, 3-2
    assert "(every pair's 90 % interval must lie inside ±1 J: two one-sided Welch tests)" in v.reason
    many = data(c1=spread(5.0, 30), c2=spread(5.2, 30), c3=spread(4.9, 30))
    assert evaluate_expectation(spec(**no_trend), many).verdict == "met"
    zigzag = data(c1=[1.0, 1.1, 1.0], c2=[3.0, 3.1, 3.0], c3=[1.0, 1.1, 1.0])
    v = evaluate_expectation(spec(**no_trend), zigzag)
    assert v.verdict == "not met" and "1.03 < 3.03 > 1.03 J" in v.reason


@pytest.mark.parametrize(
    ("relation", "extra", "verdict"),
    [
        ("greater", {}, "met"),
        ("less", {}, "not met"),
        ("equal", {"margin": 1.5}, "met"),
        ("equal", {"margin": 1.0}, "not met"),  # 1.0 +- ~0.17: the interval leaves +-1
    ],
)
def test_relations_between_configurations_use_the_welch_interval(
    relation: str, extra: dict[str, object], verdict: str
) -> None:
    v = evaluate_expectation(spec(relation=relation, configurations=[2], than=[1], **extra), RISING)
    assert v.verdict == verdict
    lo, hi = welch90([2.0, 2.2, 2.1], [1.0, 1.2, 1.1])
    assert v.reason.startswith(f"configuration 2 minus 1: 1.00 J, 90 % Welch interval [{lo:.3g}, {hi:.3g}] J")
    assert ("(fails)" in v.reason) == (verdict == "not met")


def test_the_criterion_is_stated_after_the_numbers() -> None:
    cases = {
        "greater": (dict(than=[1]), " (the 90 % interval must lie wholly above zero: one-sided test)"),
        "less": (dict(value=5.0), " (the 90 % interval must lie wholly below 5 J: one-sided test)"),
        "equal": (dict(value=2.0, margin=0.5), " (the 90 % interval must lie within ±0.5 J of 2 J: TOST)"),
        "inside": (dict(interval=[1.5, 2.5]), " (the 90 % interval must lie inside [1.5, 2.5] J)"),
    }
    for relation, (extra, text) in cases.items():
        v = evaluate_expectation(spec(relation=relation, configurations=[2], **extra), RISING)
        assert text + "; p " in v.reason, (relation, v.reason)
        assert v.verdict == "met", relation


@pytest.mark.parametrize(
    ("relation", "extra", "verdict"),
    [
        ("greater", {"value": 2.0}, "not met"),  # the 90 % interval [1.93, 2.27] reaches below 2
        ("greater", {"value": 1.9}, "met"),
        ("less", {"value": 2.3}, "met"),
        ("less", {"value": 2.2}, "not met"),
        ("equal", {"value": 2.1, "margin": 0.2}, "met"),
        ("equal", {"value": 2.1, "margin": 0.15}, "not met"),
        ("equal", {"value": 0.0, "margin": 3.0}, "met"),
        ("inside", {"interval": [1.9, 2.3]}, "met"),
        ("inside", {"interval": [1.95, 2.4]}, "not met"),
        ("inside", {"interval": [1.8, 2.25]}, "not met"),
    ],
)
def test_relations_against_a_value_use_the_t_interval(
    relation: str, extra: dict[str, object], verdict: str
) -> None:
    x = [2.0, 2.2, 2.1]
    lo, hi = stats.t.interval(0.90, 2, loc=np.mean(x), scale=stats.sem(x))  # [1.93, 2.27]
    v = evaluate_expectation(spec(relation=relation, configurations=[2], **extra), RISING)
    assert v.verdict == verdict, (v.reason, lo, hi)
    assert v.reason.startswith(f"configuration 2: mean 2.10 J, 90 % interval [{lo:.2f}, {hi:.2f}] J")
    if relation == "greater":
        ref = float(extra["value"])  # type: ignore[arg-type]
        assert v.p_value == pytest.approx(stats.ttest_1samp(x, ref, alternative="greater").pvalue)


def test_every_pair_must_hold() -> None:
    both = spec(relation="greater", configurations=[2, 3], than=[1, 1])
    assert evaluate_expectation(both, RISING).verdict == "met"
    one_fails = spec(relation="greater", configurations=[2, 1], than=[1, 3])
    v = evaluate_expectation(one_fails, RISING)
    assert v.verdict == "not met"
    first, second = v.reason.split(" (the 90 %")[0].split("; ")
    assert "(fails)" not in first and "(fails)" in second


def test_baselines_make_a_contrast() -> None:
    # what 3 adds over 1 (2.0) against what 2 adds over 1 (1.0), and against a value
    v = evaluate_expectation(
        spec(relation="greater", configurations=[3], baseline=[1], than=[2], than_baseline=[1]), RISING
    )
    assert v.verdict == "met" and v.reason.startswith("(3 minus 1) minus (2 minus 1): 1.00 J, 90 % Welch-Sat")
    v = evaluate_expectation(spec(relation="greater", configurations=[3], baseline=[1], than=[2]), RISING)
    assert v.reason.startswith("(3 minus 1) minus 2: -0.1 J, 90 % Welch-Satterthwaite interval")
    v = evaluate_expectation(spec(relation="less", configurations=[3], baseline=[1], value=2.5), RISING)
    assert v.verdict == "met" and v.reason.startswith("configuration 3 minus 1: 2.00 J, 90 % Welch interval")
    v = evaluate_expectation(
        spec(relation="greater", configurations=[3], than=[2], than_baseline=[1]), RISING
    )
    assert v.reason.startswith("(3) minus (2 minus 1): 2.10 J, 90 % Welch-Satterthwaite interval")


def test_holm_across_the_campaign_decides_and_is_shown() -> None:
    """Three expectations with one-sided p about 1e-4, 0.03 and 0.04: each alone is met at 0.05; as one
    family, Holm gives 3e-4, 0.06 and 0.06, so the last two are not met. A not-evaluable expectation is
    not a member of the family."""
    x = [0.0, 1.0, 2.0]  # mean 1, standard error 1/sqrt(3), 2 degrees of freedom
    se = stats.sem(x)

    def value_for(p: float) -> float:  # the `value` below which mean 1 has one-sided p
        return 1.0 - float(stats.t.ppf(1.0 - p, 2)) * se

    d = data(c1=x, c2=[5.0])
    specs = [
        spec(relation="greater", configurations=[1], value=value_for(p)).model_copy(update={"id": name})
        for name, p in (("a", 1e-4), ("b", 0.03), ("c", 0.04))
    ] + [spec(relation="greater", configurations=[2], value=0.0).model_copy(update={"id": "short"})]
    alone = [evaluate_expectation(s, d) for s in specs[:3]]
    assert [v.verdict for v in alone] == ["met", "met", "met"]
    assert [v.p_value for v in alone] == [pytest.approx(p) for p in (1e-4, 0.03, 0.04)]
    together = evaluate_all(specs, d)
    assert [v.verdict for v in together] == ["met", "not met", "not met", "not evaluable"]
    assert [v.p_adjusted for v in together[:3]] == [pytest.approx(p) for p in (3e-4, 0.06, 0.06)]
    assert [v.family for v in together] == [3, 3, 3, 0]
    assert math.isnan(together[3].p_adjusted) and format_p(together[3].p_adjusted) == "—"
    assert together[1].reason.endswith("; p 0.03 (Holm-adjusted over 3 expectations 0.06): not met at 0.05")
    assert (format_p(together[0].p_value), format_p(together[1].p_adjusted)) == ("< 0.001", "0.06")


def test_missing_and_short_configurations_are_not_evaluable_with_the_reason() -> None:
    d = data(c1=[1.0, 1.2], c2=[2.0])
    v = evaluate_expectation(spec(relation="increasing", configurations=[1, 2, 9]), d)
    assert v.verdict == "not evaluable"
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


def with_stops(
    d: ReportData, key: int, stops_deg: tuple[float, float], reached_deg: tuple[float, float]
) -> ReportData:
    """`d` with configuration `key` carrying a device element `stops` (range_deg) and that angle range."""
    c = d.configuration(key)
    assert c is not None
    device = (DeviceElement("stops", "rom_stops", (("range_deg", stops_deg), ("slack_deg", 3.0))),)
    new = dataclasses.replace(
        c,
        settings=SettingsView(device=device),
        angle_min_deg=reached_deg[0],
        angle_max_deg=reached_deg[1],
    )
    return dataclasses.replace(d, configurations=tuple(new if x.key == key else x for x in d.configurations))


def test_a_statement_about_stops_the_angle_never_reaches_is_not_evaluable() -> None:
    """`engages: stops`: the joint moved within [-33, 18] deg and the stops sit at [-38, 24]: nothing
    measured says whether they hold, so the statement is not evaluable (and leaves the family)."""
    about = {"relation": "inside", "configurations": [2], "interval": [1.5, 2.5], "engages": "stops"}
    unreached = with_stops(RISING, 2, (-38.0, 24.0), (-33.0, 18.0))
    v = evaluate_expectation(spec(**about), unreached)
    assert v.verdict == "not evaluable"
    assert v.reason == (
        "configuration 2's measured angle spans [-33.00, 18.00] deg and never reaches the end of 'stops' "
        "([-38, 24] deg): the statement is about 'stops', which these data never engage."
    )
    assert (
        evaluate_expectation(spec(**about), with_stops(RISING, 2, (-38.0, 24.0), (-40.0, 18.0))).verdict
        == "met"
    )
    v = evaluate_expectation(spec(**about), RISING)  # no such element
    assert v.verdict == "not evaluable" and "configuration 2 has no device element 'stops'" in v.reason


def test_a_percentile_statement_needs_its_own_end_reached() -> None:
    """A low percentile is about the low stop, a high one about the high stop; another metric is decided
    when either end is reached."""
    either = {"relation": "greater", "configurations": [2], "value": 0.0, "engages": "stops"}
    reached_high_only = with_stops(RISING, 2, (-38.0, 24.0), (-33.0, 30.0))
    assert evaluate_expectation(spec(**either), reached_high_only).verdict == "met"
    pct = spec(
        metric="angle_percentile",
        percentile=1,
        relation="inside",
        configurations=[2],
        interval=[-1, 1],
        engages="stops",
    )
    v = evaluate_expectation(pct, reached_high_only)
    assert v.verdict == "not evaluable" and "never reaches the low end of 'stops'" in v.reason


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
    inside = {"relation": "inside", "configurations": [1], "interval": [-1000, 1000]}
    for means, text in (
        ([0.01233, 0.01235], "mean 0.0123 J"),
        ([12.341, 12.343], "mean 12.34 J"),
        ([123.41, 123.43], "mean 123.4 J"),
        ([99.99, 99.99], "mean 99.99 J"),
        ([100.0, 100.0], "mean 100.0 J"),
        ([1.0, 1.0], "mean 1.00 J"),
        ([0.5, 0.5], "mean 0.5 J"),
    ):
        assert text in evaluate_expectation(spec(**inside), data(c1=means)).reason, means


def test_evaluate_all_keeps_the_declaration_order() -> None:
    specs = [
        spec(relation="increasing", configurations=[1, 2]).model_copy(update={"id": "b"}),
        spec(relation="decreasing", configurations=[1, 2]).model_copy(update={"id": "a"}),
    ]
    assert [(v.spec.id, v.verdict) for v in evaluate_all(specs, RISING)] == [("b", "met"), ("a", "not met")]


def test_a_value_exactly_on_a_bound_is_not_inside_it() -> None:
    """Constant trials (a zero-width interval): strictly inside a bound is met, exactly on it is not (the
    equivalence test's null hypothesis includes the bound), and likewise for greater / less."""
    exact = data(c1=[2.0, 2.0, 2.0])
    for interval, verdict in (([1.0, 3.0], "met"), ([1.0, 2.0], "not met"), ([2.0, 3.0], "not met")):
        v = evaluate_expectation(spec(relation="inside", configurations=[1], interval=interval), exact)
        assert v.verdict == verdict, interval
    for margin, verdict in ((0.6, "met"), (0.5, "not met")):
        v = evaluate_expectation(spec(relation="equal", configurations=[1], value=1.5, margin=margin), exact)
        assert v.verdict == verdict, margin
    for relation in ("greater", "less"):
        assert (
            evaluate_expectation(spec(relation=relation, configurations=[1], value=2.0), exact).verdict
            == "not met"
        )
    assert (
        evaluate_expectation(spec(relation="greater", configurations=[1], value=1.999), exact).verdict
        == "met"
    )
    assert (
        evaluate_expectation(spec(relation="less", configurations=[1], value=2.001), exact).verdict == "met"
    )


def test_holm_by_hand() -> None:
    """Sorted 0.01, 0.03, 0.04 of three: 3 x 0.01, max(0.03, 2 x 0.03), max(0.06, 1 x 0.04); a NaN is no
    member of the family, and no adjusted value exceeds 1."""
    from protocol_runner.analysis.statistics import holm

    got = holm([0.01, 0.04, math.nan, 0.03])
    assert got[:2] == [pytest.approx(0.03), pytest.approx(0.06)] and got[3] == pytest.approx(0.06)
    assert math.isnan(got[2])
    assert holm([0.5, 0.9]) == [1.0, 1.0]
    assert holm([]) == []
