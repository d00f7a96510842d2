"""Energy lost per cycle (thesis §5.7, Eq 10-12), on loops of known area."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.analysis.energy import (
    cycle_energy_j,
    energy_per_cycle,
    loop_integral_deg_nm,
    summarize_energy,
)
from protocol_runner.analysis.validation import AnalysisError

DEG = np.pi / 180.0


def _ellipse(
    a: float,
    b: float,
    phi: float,
    c: float = 60.0,
    d: float = 5.0,
    periods: float = 4.6,
    n_per_period: int = 800,
    start: float = 0.7,
) -> tuple[np.ndarray, np.ndarray]:
    wt = start + 2 * np.pi * np.arange(int(periods * n_per_period)) / n_per_period
    return c + a * np.sin(wt), d + b * np.sin(wt + phi)


def test_circle_area_in_deg_nm_and_joules() -> None:
    # angle = cos, torque = -sin: clockwise in (angle, torque), area pi a b (Eq 11), joules via pi/180 (Eq 12)
    wt = np.linspace(0.0, 2 * np.pi, 2001)[:-1]
    angle, torque = 10.0 * np.cos(wt), -4.0 * np.sin(wt)
    assert loop_integral_deg_nm(angle, torque) == pytest.approx(np.pi * 40.0, rel=1e-4)
    assert cycle_energy_j(angle, torque) == pytest.approx(np.pi * 40.0 * DEG, rel=1e-4)
    # the same loop the other way round (counter-clockwise) gives energy back: negative
    assert cycle_energy_j(angle, -torque) == pytest.approx(-np.pi * 40.0 * DEG, rel=1e-4)


def test_coulomb_friction_loop_is_twice_friction_times_range() -> None:
    # a brake of friction F: +F while flexing, -F while extending; loss per cycle = 2 F (max - min) pi/180
    up = np.linspace(20.0, 100.0, 400, endpoint=False)
    down = np.linspace(100.0, 20.0, 400, endpoint=False)
    angle = np.tile(np.concatenate([up, down]), 5)
    angle = np.concatenate([angle, [20.0]])
    torque = np.where(np.gradient(angle) >= 0, 3.75, -3.75) + 0.3 * angle  # plus a spring (no loss)
    e = energy_per_cycle(angle, torque)
    assert e.size == 4
    np.testing.assert_allclose(e, 2 * 3.75 * 80.0 * DEG, rtol=0.01)


@settings(max_examples=40, deadline=None)
@given(
    a=st.floats(5.0, 65.0),
    b=st.floats(0.5, 40.0),
    phi=st.floats(0.05, 3.0),
    c=st.floats(-30.0, 90.0),
    d=st.floats(-50.0, 50.0),
)
def test_elliptical_loops_of_known_area_to_half_a_percent(
    a: float, b: float, phi: float, c: float, d: float
) -> None:
    # angle = c + a sin(wt), torque = d + b sin(wt + phi): enclosed area pi a b sin(phi) (deg N m)
    angle, torque = _ellipse(a, b, phi, c, d)
    e = energy_per_cycle(angle, torque)
    assert e.size == 3  # 4.6 periods starting mid-cycle: 4 upward crossings, 3 complete cycles
    np.testing.assert_allclose(e, np.pi * a * b * np.sin(phi) * DEG, rtol=0.005)


@settings(max_examples=30, deadline=None)
@given(offset_nm=st.floats(-80.0, 80.0), shift_deg=st.floats(-60.0, 60.0))
def test_invariant_to_torque_offset_and_angle_shift(offset_nm: float, shift_deg: float) -> None:
    angle, torque = _ellipse(30.0, 8.0, 0.4)
    base = energy_per_cycle(angle, torque)
    moved = energy_per_cycle(angle + shift_deg, torque + offset_nm)
    np.testing.assert_allclose(moved, base, rtol=1e-9, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(k=st.floats(0.01, 100.0))
def test_scales_linearly_with_torque_amplitude(k: float) -> None:
    angle, torque = _ellipse(30.0, 8.0, 0.4, d=0.0)
    np.testing.assert_allclose(
        energy_per_cycle(angle, k * torque), k * energy_per_cycle(angle, torque), rtol=1e-9
    )


def test_partial_first_and_last_cycles_are_not_counted() -> None:
    # exactly three periods starting at the mean going up: the first sample is not an observed upward
    # crossing (nothing below the mean before it) and the data ends just before the fourth, so only the
    # cycle between the crossings at 1 and 2 periods is complete
    angle, torque = _ellipse(30.0, 8.0, 0.4, periods=3.0, start=0.0)
    assert energy_per_cycle(angle, torque).size == 1
    # starting at the mean going down: crossings at 0.5, 1.5 and 2.5 periods, two complete cycles
    angle, torque = _ellipse(30.0, 8.0, 0.4, periods=3.0, start=np.pi)
    assert energy_per_cycle(angle, torque).size == 2


def test_noise_neither_adds_cycles_nor_biases_the_energy() -> None:
    angle, torque = _ellipse(40.0, 10.0, 0.5, periods=8.5, n_per_period=2000)
    rng = np.random.default_rng(11)
    noisy_angle = angle + rng.normal(0.0, 0.5, angle.shape)
    e = energy_per_cycle(noisy_angle, torque)
    assert e.size == 7
    assert e.mean() == pytest.approx(np.pi * 40 * 10 * np.sin(0.5) * DEG, rel=0.02)


def test_no_complete_cycle_gives_an_empty_array() -> None:
    angle, torque = _ellipse(30.0, 8.0, 0.4, periods=0.8)
    out = energy_per_cycle(angle, torque)
    assert out.shape == (0,) and out.dtype == np.float64


def test_summary_pools_cycles_over_trials() -> None:
    s = summarize_energy([np.array([1.0, 2.0]), np.array([3.0])])
    assert (s.mean_j, s.n) == (2.0, 3)
    assert s.std_j == pytest.approx(1.0)
    one = summarize_energy(np.array([4.0]))
    assert one.n == 1 and one.mean_j == 4.0 and np.isnan(one.std_j)
    assert summarize_energy(np.zeros(0)).n == 0
    with pytest.raises(AnalysisError):
        summarize_energy(np.array([1.0, np.nan]))


def test_energy_rejects_mismatched_or_nan_input() -> None:
    with pytest.raises(AnalysisError, match="same number of samples"):
        energy_per_cycle(np.zeros(10), np.zeros(9))
    with pytest.raises(AnalysisError, match="not a finite number"):
        energy_per_cycle(np.array([0.0, np.nan, 1.0]), np.zeros(3))
