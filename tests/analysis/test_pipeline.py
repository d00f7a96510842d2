"""The processing of one configuration end to end (thesis §3.2-3.3, §4.4, §5.7, §6.1)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from protocol_runner.analysis.centring import complete_cycles_span
from protocol_runner.analysis.pipeline import Recording, TrialPair, process_configuration
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.errors import InvalidInput

from .synth import RawTrial, raw_trial

DEG = np.pi / 180.0


def _recording(r: RawTrial) -> Recording:
    return Recording(
        time_s=r.time_s,
        angle_deg=r.angle_deg,
        torque_nm=r.torque_nm,
        command_deg=r.command_deg,
        command_time_s=r.command_time_s,
    )


@pytest.fixture(scope="module")
def raw_pairs() -> list[tuple[RawTrial, RawTrial]]:
    return [(raw_trial(brace=True, seed=n), raw_trial(brace=False, seed=100 + n)) for n in (1, 2)]


@pytest.fixture(scope="module")
def pairs(raw_pairs: list[tuple[RawTrial, RawTrial]]) -> list[TrialPair]:
    return [TrialPair(_recording(on), _recording(off), trial=n) for n, (on, off) in enumerate(raw_pairs, 1)]


def test_processed_trials_follow_the_brace_on_time_base(
    pairs: list[TrialPair], raw_pairs: list[tuple[RawTrial, RawTrial]]
) -> None:
    result = process_configuration(pairs)
    assert [t.trial for t in result.trials] == [1, 2]
    for processed, (on, _) in zip(result.trials, raw_pairs, strict=True):
        start = processed.transition_index_on
        assert start > 0  # the joint started parked at 0 deg, away from the 65 deg command
        assert processed.transition_index_off > 0
        n = on.time_s.shape[0] - start
        assert processed.angle_deg.shape == processed.brace_torque_nm.shape == processed.time_s.shape == (n,)
        np.testing.assert_array_equal(processed.time_s, on.time_s[start:])
        assert processed.coverage == 1.0  # the bare robot swept a wider range than the braced one


def test_brace_torque_is_recovered_and_energy_matches_the_brake(
    pairs: list[TrialPair], raw_pairs: list[tuple[RawTrial, RawTrial]]
) -> None:
    result = process_configuration(pairs)
    for processed, (on, _) in zip(result.trials, raw_pairs, strict=True):
        truth = on.brace_true_nm[processed.transition_index_on :]
        a = processed.angle_deg
        away = (a > a.min() + 3.0) & (a < a.max() - 3.0)
        away[:300] = away[-300:] = False
        assert np.sqrt(np.mean((processed.brace_torque_nm - truth)[away] ** 2)) < 0.3
        # Coulomb brake of 3 N m: 2 F (max - min) pi / 180 per cycle; the spring part loses nothing
        expected = 2 * 3.0 * (a.max() - a.min()) * DEG
        assert processed.energy_j.size >= 3
        np.testing.assert_allclose(processed.energy_j, expected, rtol=0.05)
    # energy_loss_j: every complete cycle of every trial, in trial order, with its trial number
    np.testing.assert_array_equal(result.energy_loss_j, np.concatenate([t.energy_j for t in result.trials]))
    assert result.energy_cycle_trial.tolist() == [
        t.trial for t in result.trials for _ in range(t.energy_j.size)
    ]
    assert result.energy.n == result.energy_loss_j.size
    assert result.energy.mean_j == pytest.approx(result.energy_loss_j.mean())


def test_centred_segments_for_the_bouc_wen_fit(pairs: list[TrialPair]) -> None:
    result = process_configuration(pairs)
    segments = result.centred_segments
    assert len(segments) == 2
    for (angle, torque), trial in zip(segments, result.trials, strict=True):
        cycles = complete_cycles_span(trial.angle_deg)  # centred on the mean over its complete cycles
        assert angle[cycles].mean() == pytest.approx(0.0, abs=1e-9)
        assert torque[cycles].mean() == pytest.approx(0.0, abs=1e-9)
        np.testing.assert_allclose(angle + trial.centred.mean_angle_deg, trial.angle_deg)
    uncentred = process_configuration(pairs, ProcessingSettings(centring="none"))
    np.testing.assert_array_equal(uncentred.centred_segments[0][0], uncentred.trials[0].angle_deg)


def test_equal_time_option_gives_a_different_and_wrong_loop(
    pairs: list[TrialPair], raw_pairs: list[tuple[RawTrial, RawTrial]]
) -> None:
    by_time = process_configuration(pairs, ProcessingSettings(subtraction="equal_time"))
    processed = by_time.trials[0]
    truth = raw_pairs[0][0].brace_true_nm[processed.transition_index_on :]
    assert np.sqrt(np.mean((processed.brace_torque_nm - truth) ** 2)) > 2.0


def test_element_fit_only_when_the_device_is_given(pairs: list[TrialPair]) -> None:
    from ..knee_device import lever_spring

    assert process_configuration(pairs).elements is None
    k0 = process_configuration(pairs, device=[lever_spring(0.0, 3)])
    assert k0.elements is not None and not k0.elements.applicable
    fitted = process_configuration(pairs, device=[lever_spring(4.4, 3)])
    assert fitted.elements is not None and fitted.elements.applicable
    assert np.isfinite(fitted.elements.rmse_nm) and np.isfinite(
        fitted.elements.value("springs", "max_preload_mm")
    )


def test_chebyshev_filter_and_command_on_the_input_time_base(
    raw_pairs: list[tuple[RawTrial, RawTrial]],
) -> None:
    on, off = raw_pairs[0]

    def same_base(r: RawTrial) -> Recording:
        held = r.command_deg[np.clip(np.searchsorted(r.command_time_s, r.time_s, side="right") - 1, 0, None)]
        return Recording(r.time_s, r.angle_deg, r.torque_nm, held)

    settings = ProcessingSettings(filter_kind="chebyshev", filter_order=6, chebyshev_ripple_db=0.5)
    a = process_configuration([TrialPair(same_base(on), same_base(off))], settings)
    b = process_configuration([TrialPair(_recording(on), _recording(off))], settings)
    assert a.trials[0].transition_index_on == b.trials[0].transition_index_on
    np.testing.assert_allclose(a.trials[0].brace_torque_nm, b.trials[0].brace_torque_nm)


def test_a_trial_whose_transition_never_ends_names_the_trial(
    raw_pairs: list[tuple[RawTrial, RawTrial]],
) -> None:
    on, off = raw_pairs[0]
    stuck = Recording(
        on.time_s, np.full_like(on.angle_deg, -40.0), on.torque_nm, on.command_deg, on.command_time_s
    )
    with pytest.raises(AnalysisError, match="trial 4 brace-on: transition never ends"):
        process_configuration([TrialPair(stuck, _recording(off), trial=4)])


def test_configuration_needs_distinct_trials(pairs: list[TrialPair]) -> None:
    with pytest.raises(AnalysisError, match="at least one"):
        process_configuration([])
    with pytest.raises(AnalysisError, match="distinct"):
        process_configuration([pairs[0], pairs[0]])


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("filter_cutoff", 0.0),
        ("filter_cutoff", 1.2),
        ("filter_order", 0),
        ("filter_kind", "bessel"),
        ("subtraction", "equal_speed"),
        ("transition_points", 0),
        ("transition_tolerance_deg", -1.0),
        ("chebyshev_ripple_db", 0.0),
        ("cycle_hysteresis_deg", -2.0),
    ],
)
def test_settings_are_validated_with_the_field_name(field: str, value: object) -> None:
    with pytest.raises(InvalidInput, match=field):
        ProcessingSettings(**{field: value})  # type: ignore[arg-type]


def test_settings_describe_themselves_as_json() -> None:
    s = ProcessingSettings()
    assert json.loads(json.dumps(s.as_dict()))["filter_order"] == 10
    assert s.filter_description() == {"kind": "butterworth", "order": 10, "cutoff": 0.1, "zero_phase": True}


def test_brace_on_wider_than_brace_off_clip_or_nan(raw_pairs: list[tuple[RawTrial, RawTrial]]) -> None:
    # roles swapped on purpose: the "brace-on" trial sweeps more than its reference
    narrow, wide = raw_pairs[0]
    pair = TrialPair(brace_on=_recording(wide), brace_off=_recording(narrow))
    clipped = process_configuration([pair]).trials[0]
    assert 0.5 < clipped.coverage < 1.0
    assert np.all(np.isfinite(clipped.brace_torque_nm)) and clipped.energy_j.size > 0
    marked = process_configuration([pair], ProcessingSettings(outside="nan")).trials[0]
    assert marked.coverage == pytest.approx(clipped.coverage)
    assert np.count_nonzero(np.isnan(marked.brace_torque_nm)) == round(
        (1 - marked.coverage) * marked.angle_deg.size
    )
    # every cycle passes through the uncovered extremes: no complete cycle can be integrated
    assert marked.energy_j.size == 0
    assert np.all(np.isfinite(marked.centred.torque_nm))
