"""What `simulate` accepts: a 1-D run of finite angles, a finite start torque and a positive finite bound;
anything else is InvalidInput naming the defect."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate, simulate_trials
from tests.models.sensitivity import simulate_sensitivity

P = BoucWenParams(A=0.3, n=1.2, beta=(0.01, 0.1, -0.1, -0.05, 0.09, 0.0))


@pytest.mark.parametrize(
    ("x", "message"),
    [
        (np.zeros((2, 3)), "1-D"),
        (np.zeros(0), "empty"),
        (np.array([0.0, 1.0, np.nan, np.inf]), "non-finite value at sample 2"),
    ],
)
def test_angles_that_are_not_a_finite_1d_run_are_refused(x: np.ndarray, message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        simulate(x, P)
    with pytest.raises(InvalidInput, match=message):
        simulate_sensitivity(x, P)


@pytest.mark.parametrize("bound", [0.0, -5.0, float("inf"), float("nan")])
def test_the_divergence_bound_must_be_a_positive_finite_torque(bound: float) -> None:
    with pytest.raises(InvalidInput, match="bound_nm"):
        simulate(np.arange(3.0), P, bound_nm=bound)
    with pytest.raises(InvalidInput, match="bound_nm"):
        simulate_sensitivity(np.arange(3.0), P, bound_nm=bound)


@pytest.mark.parametrize("z0", [float("inf"), float("nan")])
def test_the_start_torque_must_be_finite(z0: float) -> None:
    with pytest.raises(InvalidInput, match="z0"):
        simulate(np.arange(3.0), P, z0=z0)
    with pytest.raises(InvalidInput, match="z0"):
        simulate_sensitivity(np.arange(3.0), P, z0=z0)


def test_one_angle_is_a_run_of_one_sample_at_the_start_torque() -> None:
    np.testing.assert_array_equal(simulate([5.0], P, z0=2.5), [2.5])
    z, dz = simulate_sensitivity([5.0], P, z0=2.5)
    np.testing.assert_array_equal(z, [2.5])
    np.testing.assert_array_equal(dz, np.zeros((1, 8)))  # z0 is held fixed: row 0 is zero


def test_the_sensitivity_run_keeps_its_first_row_zero_and_matches_simulate() -> None:
    x = 30.0 * np.sin(np.linspace(0.0, 6.0, 200))
    z, dz = simulate_sensitivity(x, P, z0=-1.0, scheme="eq23")
    np.testing.assert_array_equal(z, simulate(x, P, z0=-1.0, scheme="eq23"))
    assert dz.shape == (200, 8)
    np.testing.assert_array_equal(dz[0], 0.0)
    # Eq 23's first step z1 = z0 + d0 (A - |z0|^n Psi0) depends on A through d0 alone
    assert dz[1, 0] == pytest.approx(x[1] - x[0], rel=1e-12)


def test_by_default_the_recursion_starts_from_zero_torque() -> None:
    x = np.array([0.0, 2.0, 5.0])
    assert simulate(x, P)[0] == 0.0
    np.testing.assert_array_equal(simulate(x, P), simulate(x, P, z0=0.0))
    np.testing.assert_array_equal(simulate_sensitivity(x, P)[0], simulate(x, P, z0=0.0))


def test_any_positive_bound_is_accepted_even_below_one_newton_metre() -> None:
    z = simulate(np.array([0.0, 0.1, 0.2, 5.0]), BoucWenParams(A=1.0, n=1.0, beta=(0.0,) * 6), bound_nm=0.5)
    np.testing.assert_allclose(z[:3], [0.0, 0.1, 0.2])
    assert np.isnan(z[3])  # 5 N m is past the 0.5 N m bound


def test_every_option_of_simulate_is_optional_and_documented() -> None:
    """simulate(x, params) runs with defaults: no option is required, and each one is described where the
    options are declared."""
    from protocol_runner.models.bouc_wen.simulation import SimulateKeywords

    assert SimulateKeywords.__required_keys__ == frozenset()
    doc = SimulateKeywords.__doc__ or ""
    for key in SimulateKeywords.__optional_keys__:
        assert f"{key}:" in doc, key


def test_refining_puts_factor_minus_one_linear_samples_between_each_pair() -> None:
    """refine_angle keeps the given samples at indices 0, f, 2f, ... with f - 1 evenly spaced angles
    between each pair; f = 1 leaves the run as it is and f < 1 is refused."""
    from protocol_runner.models.bouc_wen.simulation import refine_angle

    x = np.array([0.0, 3.0, -3.0, 1.0])
    np.testing.assert_array_equal(refine_angle(x, 1), x)
    np.testing.assert_allclose(refine_angle(x, 3), [0.0, 1.0, 2.0, 3.0, 1.0, -1.0, -3.0, -5 / 3, -1 / 3, 1.0])
    for bad in (0, -1):
        with pytest.raises(InvalidInput, match="factor must be >= 1"):
            refine_angle(x, bad)


def test_the_refined_check_is_by_default_the_4x_finer_integration() -> None:
    """The rmse_refined_nm check by default: the angle 4 times finer, substeps 4 times shorter than the
    default 0.1 deg, the torque compared at the given samples."""
    from protocol_runner.models.bouc_wen.problem import refined_rmse
    from protocol_runner.models.bouc_wen.simulation import refine_angle

    x = 50.0 * np.sin(np.linspace(0.0, 6.0, 40))
    y = np.cos(np.linspace(0.0, 6.0, 40))
    fine = simulate(refine_angle(x, 4), P, y[0], max_step_deg=0.025)[::4]
    assert refined_rmse([(x, y)], P, 1e6) == pytest.approx(math.sqrt(float(np.sum((fine - y) ** 2)) / y.size))
    np.testing.assert_array_equal(refine_angle(x), refine_angle(x, 4))


def test_several_trials_are_each_their_own_simulation_and_need_one_start_each() -> None:
    """Trials of different lengths from their own starting torques, in one call: each is bit for bit what
    `simulate` gives it alone; a starting torque missing or left over is named, not guessed."""
    params = P
    xs = [40.0 * np.sin(np.linspace(0.0, 4 * np.pi, n)) for n in (300, 451)]
    together = simulate_trials(xs, params, [0.0, -3.5])
    for x, z0, torque in zip(xs, (0.0, -3.5), together, strict=True):
        np.testing.assert_array_equal(torque, simulate(x, params, z0))
    for starts in ([0.0], [0.0, 1.0, 2.0]):
        with pytest.raises(InvalidInput, match=f"2 trials but {len(starts)} starting torques"):
            simulate_trials(xs, params, starts)
