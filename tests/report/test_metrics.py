"""The metric library (report/headline.py) on hand-made trials whose answers are known: one value per trial.

Each trial is a loop swept at constant speed, up from 10 deg to 100 deg and back down, with brace torque
`slope * angle + width/2` on the way up and `- width/2` on the way down (a friction band of the given width
around a linear spring): its least-squares slope is the spring's, its hysteresis width the band's, its peak
torque the band's edge at 100 deg.
"""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.report.headline import HYSTERESIS_WINDOW_DEG, LABELS, UNITS, trial_values
from protocol_runner.report.model import BoucWenFit, Configuration, ProcessedTrial, Trial
from protocol_runner.report.settings_view import SettingsView

LOW, HIGH = 10.0, 100.0


def loop(slope: float, width: float, n: int = 901, low: float = LOW, high: float = HIGH) -> ProcessedTrial:
    up = np.linspace(low, high, n)
    angle = np.concatenate([up, up[::-1][1:]])
    sign = np.concatenate([np.ones(n), -np.ones(n - 1)])
    torque = slope * angle + sign * width / 2.0
    return ProcessedTrial(angle_deg=angle, brace_torque_nm=torque, subtraction="equal_angle")


def fit(rmse: float, cv: tuple[float, ...]) -> BoucWenFit:
    empty = np.zeros(0)
    return BoucWenFit(
        angle_deg=empty,
        torque_nm=empty,
        model_torque_nm=empty,
        A=1.0,
        n=1.0,
        beta=(),
        rmse_nm=rmse,
        r2=0.9,
        cv_rmse_nm=cv,
        n_starts=1,
    )


def config(
    processed: list[ProcessedTrial | None],
    energy: list[float] | None = None,
    ids: list[int] | None = None,
    bouc_wen: BoucWenFit | None = None,
) -> Configuration:
    trials = tuple(Trial(i + 1, None, None, p) for i, p in enumerate(processed))
    return Configuration(
        name="config_1",
        key=1,
        joint="j",
        run=1,
        set_name="s",
        condition="",
        profile="sinusoid",
        status="complete",
        n_trials_planned=len(trials),
        settings=SettingsView(),
        trials=trials,
        energy_loss_j=np.asarray(energy or [], dtype=float),
        energy_cycle_trial=np.asarray(ids or [], dtype=float),
        bouc_wen=bouc_wen,
        element_fit=None,
        angle_min_deg=LOW,
        angle_max_deg=HIGH,
    )


def test_every_metric_has_a_unit_and_a_label() -> None:
    assert set(UNITS) == set(LABELS)
    assert UNITS["energy_per_cycle"] == "J" and UNITS["energy_per_degree"] == "J/deg"
    assert UNITS["torque_angle_slope"] == "N·m/deg" and UNITS["range_reached"] == "deg"


def test_slope_of_a_spring_with_a_friction_band_is_the_spring_rate() -> None:
    cfg = config([loop(0.3, 2.0), loop(0.5, 0.4)])
    # the way down has one sample fewer (the turn is shared), so the band tilts the fit by < 1e-4
    assert trial_values(cfg, "torque_angle_slope") == pytest.approx((0.3, 0.5), rel=2e-4)


def test_range_and_percentiles_of_the_angle_reached() -> None:
    cfg = config([loop(0.3, 2.0), loop(0.3, 2.0, low=20.0, high=80.0)])
    p1 = (
        np.percentile(loop(0.3, 2.0).angle_deg, 1),
        np.percentile(loop(0.3, 2.0, 901, 20.0, 80.0).angle_deg, 1),
    )
    assert trial_values(cfg, "angle_percentile", percentile=1) == pytest.approx(p1)
    assert trial_values(cfg, "angle_percentile", percentile=100) == pytest.approx((HIGH, 80.0))
    assert trial_values(cfg, "angle_percentile", percentile=0) == pytest.approx((LOW, 20.0))
    ranges = trial_values(cfg, "range_reached")
    # 98 % of a uniform sweep: (high - low) * 0.98
    assert ranges == pytest.approx((0.98 * (HIGH - LOW), 0.98 * 60.0), rel=1e-3)
    # without a percentile the median is taken
    assert trial_values(cfg, "angle_percentile") == pytest.approx((55.0, 50.0), abs=0.1)


def test_peak_torque_is_the_largest_absolute_torque() -> None:
    # a rising spring peaks at the top on the way up: 0.3 * 100 + 1; a falling one on the way down, whose
    # first sample is one step (0.1 deg) below the top: 0.3 * 99.9 + 1
    neg = loop(-0.3, 2.0)
    assert trial_values(config([loop(0.3, 2.0), neg]), "peak_torque") == pytest.approx((31.0, 30.97))


def test_hysteresis_width_is_the_gap_between_the_two_directions_near_the_angle() -> None:
    cfg = config([loop(0.3, 2.0), loop(0.3, 0.5)])
    assert trial_values(cfg, "hysteresis_width", angle_deg=50.0) == pytest.approx((2.0, 0.5), rel=1e-6)
    # outside the swept range there is nothing to compare: the trial gives no value
    assert trial_values(cfg, "hysteresis_width", angle_deg=HIGH + 3 * HYSTERESIS_WINDOW_DEG) == ()
    assert trial_values(cfg, "hysteresis_width") == ()  # no angle given


def test_hysteresis_needs_both_directions_within_the_window() -> None:
    one_way = ProcessedTrial(np.linspace(LOW, HIGH, 500), np.linspace(0.0, 5.0, 500), "equal_angle")
    assert trial_values(config([one_way]), "hysteresis_width", angle_deg=50.0) == ()
    assert HYSTERESIS_WINDOW_DEG == 2.0


def test_energy_per_cycle_is_the_mean_of_each_trials_cycles() -> None:
    cfg = config([loop(0.3, 2.0), loop(0.3, 2.0)], energy=[1.0, 3.0, 10.0, 14.0], ids=[1, 1, 2, 2])
    assert trial_values(cfg, "energy_per_cycle") == (2.0, 12.0)


def test_energy_per_degree_divides_each_trials_energy_by_its_range() -> None:
    cfg = config(
        [loop(0.3, 2.0), loop(0.3, 2.0, low=20.0, high=80.0)], energy=[4.0, 6.0, 3.0, 3.0], ids=[1, 1, 2, 2]
    )
    r1, r2 = trial_values(cfg, "range_reached")
    assert trial_values(cfg, "energy_per_degree") == pytest.approx((5.0 / r1, 3.0 / r2), rel=1e-12)


def test_energy_per_degree_skips_a_trial_without_range() -> None:
    flat = ProcessedTrial(np.full(50, 30.0), np.zeros(50), "equal_angle")
    cfg = config([flat, loop(0.3, 2.0)], energy=[4.0, 6.0], ids=[1, 2])
    (value,) = trial_values(cfg, "energy_per_degree")
    assert value == pytest.approx(6.0 / (0.98 * (HIGH - LOW)), rel=1e-3)
    no_processed = config([None, loop(0.3, 2.0)], energy=[4.0, 6.0], ids=[1, 2])
    assert len(trial_values(no_processed, "energy_per_degree")) == 1


def test_fit_rmse_is_the_held_out_rmse_or_the_fit_itself_with_one_trial() -> None:
    assert trial_values(config([]), "fit_rmse") == ()
    assert trial_values(config([], bouc_wen=fit(0.4, (0.5, 0.7))), "fit_rmse") == (0.5, 0.7)
    assert trial_values(config([], bouc_wen=fit(0.4, ())), "fit_rmse") == (0.4,)


def test_trials_without_processed_data_or_with_nan_give_no_value() -> None:
    nan_trial = ProcessedTrial(np.full(10, np.nan), np.full(10, np.nan), "equal_angle")
    cfg = config([None, nan_trial, loop(0.3, 2.0)])
    for metric in ("torque_angle_slope", "range_reached", "peak_torque"):
        assert len(trial_values(cfg, metric)) == 1, metric
    assert len(trial_values(cfg, "angle_percentile", percentile=99)) == 1


def test_a_slope_needs_three_samples_and_some_motion() -> None:
    short = ProcessedTrial(np.array([1.0, 2.0]), np.array([0.1, 0.2]), "equal_angle")
    still = ProcessedTrial(np.full(20, 30.0), np.linspace(0.0, 1.0, 20), "equal_angle")
    three = ProcessedTrial(np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.0, 1.5]), "equal_angle")
    assert trial_values(config([short, still]), "torque_angle_slope") == ()
    assert trial_values(config([three]), "torque_angle_slope") == pytest.approx((0.5,))


def test_unequal_lengths_use_the_common_samples() -> None:
    p = loop(0.3, 2.0)
    longer = ProcessedTrial(np.concatenate([p.angle_deg, [500.0]]), p.brace_torque_nm, "equal_angle")
    assert trial_values(config([longer]), "angle_percentile", percentile=100) == pytest.approx((HIGH,))


def test_an_unknown_metric_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown metric 'energy'"):
        trial_values(config([loop(0.3, 2.0)]), "energy")


def test_the_shortest_loop_has_a_width_and_fewer_samples_give_no_value() -> None:
    """Out and back in three samples (49 -> 50 -> 49 deg, torque +1 on the way out, -1 on the way back) is a
    loop 2 N*m wide; one or two samples cannot go both ways, and a trial with too few finite samples gives
    no value (never an error)."""
    three = ProcessedTrial(np.array([49.0, 50.0, 49.0]), np.array([1.0, 5.0, -1.0]), "equal_angle")
    assert trial_values(config([three]), "hysteresis_width", angle_deg=50.0) == pytest.approx((2.0,))
    for n in (0, 1, 2):
        short = ProcessedTrial(three.angle_deg[:n], three.brace_torque_nm[:n], "equal_angle")
        assert trial_values(config([short]), "hysteresis_width", angle_deg=50.0) == (), n
    nan_padded = ProcessedTrial(np.array([49.0, np.nan, np.nan]), np.array([1.0, 5.0, -1.0]), "equal_angle")
    assert trial_values(config([nan_padded]), "hysteresis_width", angle_deg=50.0) == ()


def test_the_hysteresis_width_is_the_mean_gap_over_the_whole_window() -> None:
    """A band that widens away from 50 deg, gap 2 + (angle - 50)^2 / 4 N*m: its width at 50 deg is the gap's
    mean over 50 +- HYSTERESIS_WINDOW_DEG, 2 + (2^2 / 3) / 4 = 2.333 N*m (not the gap at 50 deg, 2, nor at
    the window's edges, 3)."""
    up = np.linspace(LOW, HIGH, 9001)
    angle = np.concatenate([up, up[::-1][1:]])
    sign = np.concatenate([np.ones(up.size), -np.ones(up.size - 1)])
    torque = 0.3 * angle + sign * (2.0 + (angle - 50.0) ** 2 / 4.0) / 2.0
    p = ProcessedTrial(angle_deg=angle, brace_torque_nm=torque, subtraction="equal_angle")
    expected = 2.0 + (HYSTERESIS_WINDOW_DEG**2 / 3.0) / 4.0
    assert trial_values(config([p]), "hysteresis_width", angle_deg=50.0) == pytest.approx(
        (expected,), rel=1e-3
    )


def test_a_small_range_still_gives_an_energy_per_degree() -> None:
    """Any range above zero divides: a trial sweeping 0.5 deg (49.75 to 50.25) losing 0.1 J per cycle loses
    0.1 / (0.98 * 0.5) J per degree of its range reached."""
    small = loop(0.3, 2.0, low=49.75, high=50.25)
    (value,) = trial_values(config([small], energy=[0.1], ids=[1]), "energy_per_degree")
    assert value == pytest.approx(0.1 / (0.98 * 0.5), rel=1e-3)
