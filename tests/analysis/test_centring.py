"""Centring of a loop on (0, 0) by the trial mean over its complete cycles (thesis §6.2.3 note)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.centring import centre, complete_cycles_span
from protocol_runner.analysis.cycles import upward_crossings
from protocol_runner.analysis.energy import energy_per_cycle


def test_centred_loop_has_zero_mean_over_its_cycles_and_keeps_the_means() -> None:
    t = np.linspace(0.0, 10.0, 5001)
    angle = 65.0 + 40.0 * np.sin(2 * np.pi * t / 2.5)
    torque = 12.0 + 8.0 * np.sin(2 * np.pi * t / 2.5 + 0.4)
    loop = centre(angle, torque)
    span = complete_cycles_span(angle)
    assert loop.angle_deg[span].mean() == pytest.approx(0.0, abs=1e-9)
    assert loop.torque_nm[span].mean() == pytest.approx(0.0, abs=1e-9)
    assert loop.mean_angle_deg == pytest.approx(65.0, abs=1e-3)
    assert loop.mean_torque_nm == pytest.approx(12.0, abs=1e-3)
    np.testing.assert_allclose(loop.angle_deg + loop.mean_angle_deg, angle)
    # centring moves the loop, it does not change its area
    np.testing.assert_allclose(
        energy_per_cycle(loop.angle_deg, loop.torque_nm), energy_per_cycle(angle, torque)
    )


def test_trials_cut_at_different_points_are_centred_on_the_same_point() -> None:
    """One steady loop recorded to two different ends (a stop mid-cycle in one), both starting as a record
    does after its transition cut (§3.3.1: within 5 deg of the command, here 4 deg low, closing with the
    servo's 0.2 s lag): the whole-record means differ by a degree, the means over complete cycles are the
    loop's centre in both."""
    t = np.arange(0.0, 12.0, 0.002)
    phase = 2 * np.pi * t / 2.5
    angle = 50.0 + 30.0 * np.sin(phase) - 4.0 * np.exp(-t / 0.2)
    torque = 5.0 + 10.0 * np.sin(phase + 0.5)
    whole = centre(angle, torque)
    short = centre(angle[:4500], torque[:4500])  # stops 9 s in, a 0.6-cycle tail
    assert abs(whole.mean_angle_deg - short.mean_angle_deg) < 0.12
    assert abs(whole.mean_torque_nm - short.mean_torque_nm) < 0.05
    for loop in (whole, short):  # the first cycle still holds the end of the lag's closing
        assert loop.mean_angle_deg == pytest.approx(50.0, abs=0.15)
        assert loop.mean_torque_nm == pytest.approx(5.0, abs=0.05)
    # the record's own mean is pulled away by the partial cycle
    assert abs(float(angle[:4500].mean()) - float(angle.mean())) > 1.0


def test_a_trial_without_a_complete_cycle_is_centred_on_all_its_samples() -> None:
    angle = np.linspace(10.0, 40.0, 500)
    torque = np.linspace(-2.0, 4.0, 500)
    loop = centre(angle, torque)
    assert loop.mean_angle_deg == pytest.approx(25.0) and loop.mean_torque_nm == pytest.approx(1.0)


def test_the_means_are_taken_from_the_first_upward_crossing_to_the_last() -> None:
    """4.6 periods starting past a peak: three complete cycles lie between the first upward crossing of the
    mean and the last. A torque of 100 N*m outside them (a start transient, a stop) moves nothing: the
    means are those of the complete cycles, every one of them."""
    t = np.arange(0.0, 4.6 * 2.5, 0.002)
    angle = 30.0 * np.sin(2 * np.pi * t / 2.5 + 2.0)
    crossings = upward_crossings(angle)
    assert crossings.size == 4
    span = complete_cycles_span(angle)
    assert (span.start, span.stop) == (crossings[0], crossings[-1])
    inside = np.zeros(t.size, dtype=bool)
    inside[span] = True
    torque = np.where(inside, 3.0 + 8.0 * np.cos(2 * np.pi * t / 2.5), 100.0)
    loop = centre(angle, torque)
    assert loop.mean_torque_nm == pytest.approx(float(torque[inside].mean()), abs=1e-12)
    assert loop.mean_torque_nm == pytest.approx(3.0, abs=0.01)
    assert loop.mean_angle_deg == pytest.approx(float(angle[inside].mean()), abs=1e-12)
