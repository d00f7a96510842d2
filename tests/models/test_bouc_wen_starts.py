"""The data-driven starting points of the Bouc-Wen fit are exact on noise-free Eq 23 data whose A and n
they assume (Figure 56: A = n = 1) or whose n lies on their grid (equation error)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.models.bouc_wen.fitting import equation_error_start, thesis_start
from protocol_runner.models.bouc_wen.params import BoucWenParams, phase_of_samples, phase_values
from protocol_runner.models.bouc_wen.simulation import simulate

BETA = (0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036)


def _two_trials(params: BoucWenParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(0.0, 12.0, 0.05)
    x1 = 50.0 * np.sin(2 * np.pi * t / 8.17)
    x2 = 35.0 * np.sin(2 * np.pi * t / 6.0 + 1.0)
    y1 = simulate(x1, params, z0=-3.0, scheme="eq23")
    y2 = simulate(x2, params, z0=2.0, scheme="eq23")
    seg = np.array([0, x1.size, x1.size + x2.size], dtype=np.int64)
    return np.concatenate([x1, x2]), np.concatenate([y1, y2]), seg


def test_every_table4_phase_is_visited_by_the_test_data() -> None:
    params = BoucWenParams(A=1.0, n=1.0, beta=BETA)
    x, y, seg = _two_trials(params)
    phases = set(phase_of_samples(x[: seg[1]], y[: seg[1]]).tolist())
    assert {1, 2, 3, 4, 5, 6} <= phases


def test_figure56_guess_is_exact_when_a_and_n_are_one() -> None:
    # Eq 23 solved for Psi on every step gives the true phase value; the median of equal values is it
    params = BoucWenParams(A=1.0, n=1.0, beta=BETA)
    x, y, seg = _two_trials(params)
    guess = thesis_start(x, y, seg)
    assert (guess.A, guess.n) == (1.0, 1.0)
    np.testing.assert_allclose(phase_values(guess.beta), phase_values(params.beta), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("n", [0.6, 1.5])
def test_equation_error_guess_is_exact_for_n_on_its_grid(n: float) -> None:
    # exact only if no equation joins the last sample of trial 1 to the first of trial 2 (their torques
    # start apart, so such a step would not satisfy Eq 23)
    params = BoucWenParams(A=0.35, n=n, beta=BETA)
    x, y, seg = _two_trials(params)
    guess = equation_error_start(x, y, seg, np.array([0.3, 0.6, 1.0, 1.5, 2.0]))
    assert guess is not None
    assert guess.n == n
    np.testing.assert_allclose(guess.as_array(), params.as_array(), rtol=1e-6, atol=1e-9)


def test_equation_error_guess_needs_enough_moving_steps() -> None:
    x = np.array([0.0, 1.0, 1.0, 2.0, 2.0])
    y = np.array([0.0, 0.5, 0.5, 0.8, 0.8])
    assert equation_error_start(x, y, np.array([0, 5]), np.array([1.0])) is None


def test_held_angles_and_zero_torque_carry_no_phase_information() -> None:
    """A step where the angle holds still (Eq 23: dz = 0) or starts from z = 0 (|z|^n = 0) says nothing
    about Psi; the Figure 56 guess skips those steps and stays exact (and divides by nothing)."""
    params = BoucWenParams(A=1.0, n=1.0, beta=BETA)
    t = np.arange(0.0, 12.0, 0.05)
    x = np.repeat(50.0 * np.sin(2 * np.pi * t / 8.17), 2)  # every angle held for two samples
    y = simulate(x, params, z0=0.0, scheme="eq23")  # the trial starts at exactly zero torque
    guess = thesis_start(x, y, np.array([0, x.size], dtype=np.int64))
    np.testing.assert_allclose(phase_values(guess.beta), phase_values(params.beta), rtol=1e-6, atol=1e-9)


def test_both_guesses_are_exact_on_whole_degree_steps_from_zero_torque() -> None:
    """Angles on a whole-degree grid (every step exactly +-1 deg) and a trial starting at exactly zero
    torque (its first step has |z|^n = 0): every step is still a valid equation of Eq 23."""
    x = np.concatenate([np.arange(0.0, 40.0), np.arange(40.0, -40.0, -1.0), np.arange(-40.0, 41.0)])
    one = BoucWenParams(A=1.0, n=1.0, beta=BETA)
    y = simulate(x, one, z0=0.0, scheme="eq23")
    seg = np.array([0, x.size], dtype=np.int64)
    np.testing.assert_allclose(
        phase_values(thesis_start(x, y, seg).beta), phase_values(one.beta), rtol=1e-6, atol=1e-9
    )
    params = BoucWenParams(A=0.35, n=1.5, beta=BETA)
    y = simulate(x, params, z0=0.0, scheme="eq23")
    guess = equation_error_start(x, y, seg, np.array([1.0, 1.5]))
    assert guess is not None
    np.testing.assert_allclose(guess.as_array(), params.as_array(), rtol=1e-6, atol=1e-9)


def test_a_trial_of_two_samples_is_one_step_of_eq23() -> None:
    """Two samples make one Eq 23 step, a whole equation for both guesses: a loop cut into two-sample
    trials (every other step, none joining two trials) still gives the exact parameters."""
    one = BoucWenParams(A=1.0, n=1.0, beta=BETA)
    x, y, seg = _two_trials(one)
    pairs = np.arange(0, seg[1] - 1, 2, dtype=np.int64)
    cut = np.append(pairs, pairs[-1] + 2)
    xs, ys = x[: cut[-1]], y[: cut[-1]]
    np.testing.assert_allclose(
        phase_values(thesis_start(xs, ys, cut).beta), phase_values(one.beta), rtol=1e-6, atol=1e-9
    )
    params = BoucWenParams(A=0.35, n=1.5, beta=BETA)
    x, y, seg = _two_trials(params)
    guess = equation_error_start(x[: cut[-1]], y[: cut[-1]], cut, np.array([1.0, 1.5]))
    assert guess is not None
    np.testing.assert_allclose(guess.as_array(), params.as_array(), rtol=1e-6, atol=1e-9)
