"""Processing settings at their limits: the smallest values that make sense are accepted, the first that
do not are refused with the field's name (exit status 2)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.pipeline import Recording, TrialPair
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.errors import InvalidInput


def test_the_smallest_meaningful_values_are_accepted() -> None:
    s = ProcessingSettings(
        transition_points=1,
        filter_order=1,
        filter_cutoff=0.999,
        cycle_hysteresis_deg=0.0,
        transition_tolerance_deg=1e-9,
        bin_width_deg=1e-9,
        reversal_deg=1e-9,
        chebyshev_ripple_db=1e-9,
    )
    assert s.transition_points == 1 and s.cycle_hysteresis_deg == 0.0
    assert ProcessingSettings(cycle_hysteresis_deg=2.5).cycle_hysteresis_deg == 2.5  # a band, not only none


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("transition_tolerance_deg", 0.0),
        ("transition_points", True),
        ("filter_order", True),
        ("filter_order", 2.0),
        ("filter_cutoff", 1.0),
        ("bin_width_deg", 0.0),
        ("reversal_deg", 0.0),
        ("command_resampling", "cubic"),
        ("outside", "extrapolate"),
        ("cycle_reference", "median"),
        ("centring", "trial_median"),
        ("element_fit_target", "upper_branch"),
    ],
)
def test_the_first_value_past_each_limit_is_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(InvalidInput, match=f"processing settings: {field} "):
        ProcessingSettings(**{field: value})  # type: ignore[arg-type]


def test_the_chebyshev_ripple_is_described_only_for_a_chebyshev_filter() -> None:
    cheb = ProcessingSettings(
        filter_kind="chebyshev", filter_order=4, filter_cutoff=0.2, chebyshev_ripple_db=1.0
    )
    assert cheb.filter_description() == {
        "kind": "chebyshev",
        "order": 4,
        "cutoff": 0.2,
        "ripple_db": 1.0,
        "zero_phase": True,
    }
    assert "ripple_db" not in ProcessingSettings(chebyshev_ripple_db=1.0).filter_description()


def test_a_pair_without_a_trial_number_is_trial_1() -> None:
    rec = Recording(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    assert TrialPair(rec, rec).trial == 1  # trials are numbered from 1, as in the archive


def test_the_cut_off_in_hz_is_the_fraction_of_nyquist_at_the_rate_filtered() -> None:
    described = ProcessingSettings().filter_description(333.0)  # 0.1 of a 166.5 Hz Nyquist frequency
    assert described["cutoff_hz"] == pytest.approx(16.65, rel=1e-12) and described["sample_rate_hz"] == 333.0
    assert "cutoff_hz" not in ProcessingSettings().filter_description()


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("filter_cutoff", 0.0),
        ("cycle_hysteresis_deg", -0.1),
        ("transition_points", 0),
        ("chebyshev_ripple_db", -1.0),
    ],
)
def test_the_first_value_below_each_limit_is_refused_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(InvalidInput, match=f"processing settings: {field} "):
        ProcessingSettings(**{field: value})  # type: ignore[arg-type]


def test_a_method_outside_its_choices_is_refused_with_the_choices() -> None:
    with pytest.raises(
        InvalidInput, match="subtraction must be 'equal_angle' or 'equal_time', got 'equal_speed'"
    ):
        ProcessingSettings(subtraction="equal_speed")  # type: ignore[arg-type]
