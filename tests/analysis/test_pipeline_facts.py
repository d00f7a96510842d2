"""The processing of hand-made configurations whose answers are known: a brace-on trial identical to its
brace-off trial has no brace torque; cycles that stay inside the brace-off range keep their energy when
others leave it (outside="nan"); an uncentred loop reports zero means; a spring fit the loop cannot
support is "not applicable" with the reason."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.centring import complete_cycles_span
from protocol_runner.analysis.pipeline import Recording, TrialPair, process_configuration
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.errors import InvalidInput

from ..knee_device import lever_spring

RATE_HZ = 100.0
PERIOD_S = 10.0
DEG = np.pi / 180.0


def _recording(angle: np.ndarray, torque: np.ndarray) -> Recording:
    t = np.arange(angle.size) / RATE_HZ
    return Recording(time_s=t, angle_deg=angle, torque_nm=torque, command_deg=angle.copy())


def _sweep(amplitudes: list[float]) -> np.ndarray:
    """65 deg + one sine cycle per amplitude, starting at the mean going up."""
    k = np.arange(int(PERIOD_S * RATE_HZ))
    return np.concatenate([65.0 + a * np.sin(2 * np.pi * k / k.size) for a in amplitudes])


def _robot(angle: np.ndarray) -> np.ndarray:
    return 35.0 * np.sin(np.radians(angle)) + 4.0 * np.sign(np.gradient(angle))


def test_a_brace_on_trial_identical_to_its_brace_off_trial_has_no_brace_torque() -> None:
    angle = _sweep([40.0] * 4)
    rec = _recording(angle, _robot(angle))
    result = process_configuration([TrialPair(rec, rec)], ProcessingSettings(subtraction="equal_time"))
    trial = result.trials[0]
    np.testing.assert_allclose(trial.brace_torque_nm, 0.0, atol=1e-9)
    np.testing.assert_allclose(
        trial.robot_torque_nm + trial.brace_torque_nm, trial.robot_torque_nm, atol=1e-9
    )
    assert trial.coverage == 1.0
    np.testing.assert_allclose(trial.energy_j, 0.0, atol=1e-9)


def test_cycles_inside_the_brace_off_range_keep_their_energy_when_later_ones_leave_it() -> None:
    off_angle = _sweep([40.0] * 5)  # covers 25..105 deg
    on_angle = _sweep([30.0, 30.0, 30.0, 50.0, 50.0])  # three cycles inside, two beyond
    brake_nm = 3.0
    off = _recording(off_angle, _robot(off_angle))
    on = _recording(on_angle, _robot(on_angle) + brake_nm * np.sign(np.gradient(on_angle)))
    result = process_configuration([TrialPair(on, off)], ProcessingSettings(outside="nan"))
    trial = result.trials[0]
    assert 0.5 < trial.coverage < 1.0
    # complete cycles (between upward crossings of the mean) wholly inside the covered stretch: 2
    assert trial.energy_j.size == 2
    np.testing.assert_allclose(trial.energy_j, 2 * brake_nm * 60.0 * DEG, rtol=0.03)
    assert result.energy.n == 2


def test_an_uncentred_loop_is_the_processed_loop_with_zero_means() -> None:
    angle = _sweep([40.0] * 3)
    off = _recording(angle, _robot(angle))
    on = _recording(angle, _robot(angle) + 2.0 + 0.1 * angle)
    result = process_configuration([TrialPair(on, off)], ProcessingSettings(centring="none"))
    trial = result.trials[0]
    assert trial.centred.mean_angle_deg == 0.0 and trial.centred.mean_torque_nm == 0.0
    np.testing.assert_array_equal(trial.centred.angle_deg, trial.angle_deg)
    np.testing.assert_array_equal(trial.centred.torque_nm, trial.brace_torque_nm)
    centred = process_configuration([TrialPair(on, off)]).trials[0].centred
    cycles = complete_cycles_span(trial.angle_deg)  # the means over the complete cycles
    assert centred.mean_angle_deg == pytest.approx(float(np.mean(trial.angle_deg[cycles])))
    assert centred.mean_torque_nm == pytest.approx(float(np.mean(trial.brace_torque_nm[cycles])))


def test_an_element_fit_the_loop_cannot_support_is_not_applicable_with_the_reason() -> None:
    angle = _sweep([4.0] * 4)  # +-4 deg: nothing left once 5 deg are trimmed at each end
    off = _recording(angle, _robot(angle))
    on = _recording(angle, _robot(angle) + 0.5 * (angle - 65.0))
    result = process_configuration([TrialPair(on, off)], device=[lever_spring(13.0, 3)])
    assert result.elements is not None and not result.elements.applicable
    assert result.elements.reason.startswith("not applicable: ")
    assert "no loop midline" in result.elements.reason
    assert result.elements.fitted == () and np.isnan(result.elements.rmse_nm)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("filter_cutoff", -0.1),
        ("filter_cutoff", 0.0),
        ("bin_width_deg", -0.5),
        ("reversal_deg", -1.0),
        ("transition_tolerance_deg", -5.0),
        ("cycle_hysteresis_deg", -0.5),
    ],
)
def test_a_negative_size_or_cut_off_is_refused(field: str, value: float) -> None:
    with pytest.raises(InvalidInput, match=f"processing settings: {field} "):
        ProcessingSettings(**{field: value})  # type: ignore[arg-type]


def test_any_non_negative_cycle_hysteresis_is_accepted() -> None:
    for hysteresis_deg in (0.0, 0.5, 2.0, 30.0):
        assert ProcessingSettings(cycle_hysteresis_deg=hysteresis_deg).cycle_hysteresis_deg == hysteresis_deg


def test_the_cut_off_in_hz_is_that_fraction_of_the_nyquist_frequency() -> None:
    """Thesis §3.2 note: the cut-off is a fraction of half the sampling frequency; 10 % at 1 kHz is 50 Hz."""
    described = ProcessingSettings().filter_description(1000.0)
    assert described["cutoff_hz"] == pytest.approx(50.0) and described["sample_rate_hz"] == 1000.0
    assert ProcessingSettings(filter_cutoff=0.25).filter_description(200.0)["cutoff_hz"] == pytest.approx(
        25.0
    )


def test_a_brace_off_trial_that_cannot_serve_as_reference_is_named() -> None:
    """A brace-off trial that only flexes (no unloading branch) gives no robot torque at equal angles: the
    error names the trial and the brace-off run, so the operator knows which recording to redo."""
    angle = _sweep([40.0] * 3)
    ramp = np.linspace(25.0, 105.0, angle.size)
    pair = TrialPair(_recording(angle, _robot(angle)), _recording(ramp, _robot(ramp)), trial=3)
    with pytest.raises(InvalidInput, match=r"^trial 3 brace-off: the trial has no usable unloading branch"):
        process_configuration([pair])


@pytest.mark.parametrize("centring", ["none", "trial_mean"])
def test_a_loop_with_undefined_brace_torques_keeps_only_the_defined_samples(centring: str) -> None:
    """outside="nan": samples beyond the brace-off range have no brace torque; the loop handed to the
    Bouc-Wen fit keeps the others, uncentred with zero means or centred on their own means."""
    off_angle = _sweep([40.0] * 3)
    on_angle = _sweep([30.0, 50.0, 30.0])
    off = _recording(off_angle, _robot(off_angle))
    on = _recording(on_angle, _robot(on_angle) + 0.1 * on_angle)
    settings = ProcessingSettings(outside="nan", centring=centring)  # type: ignore[arg-type]
    trial = process_configuration([TrialPair(on, off)], settings).trials[0]
    defined = np.isfinite(trial.brace_torque_nm)
    assert 0 < np.count_nonzero(~defined) < defined.size
    angle, torque = trial.angle_deg[defined], trial.brace_torque_nm[defined]
    loop = trial.centred
    if centring == "none":
        assert loop.mean_angle_deg == 0.0 and loop.mean_torque_nm == 0.0
        np.testing.assert_array_equal(loop.angle_deg, angle)
        np.testing.assert_array_equal(loop.torque_nm, torque)
    else:
        cycles = complete_cycles_span(angle)  # the means over the complete cycles of the defined samples
        assert loop.mean_angle_deg == pytest.approx(float(np.mean(angle[cycles])))
        assert loop.mean_torque_nm == pytest.approx(float(np.mean(torque[cycles])))
        np.testing.assert_allclose(loop.angle_deg, angle - np.mean(angle[cycles]))


def test_an_equal_time_subtraction_leaves_the_brace_torque() -> None:
    """The (wrong, §5.6) equal-time method on a brace-on run with the robot's exact motion: what is left is
    the brace's own torque, and the robot's torque is the brace-off run's."""
    angle = _sweep([40.0] * 3)
    off = _recording(angle, _robot(angle))
    on = _recording(angle, _robot(angle) + 2.0 + 0.1 * angle)
    trial = process_configuration([TrialPair(on, off)], ProcessingSettings(subtraction="equal_time")).trials[
        0
    ]
    np.testing.assert_allclose(trial.brace_torque_nm, 2.0 + 0.1 * trial.angle_deg, atol=1e-3)
    on_only = process_configuration([TrialPair(on, on)], ProcessingSettings(subtraction="equal_time"))
    np.testing.assert_allclose(
        trial.robot_torque_nm + trial.brace_torque_nm, on_only.trials[0].robot_torque_nm
    )
