"""The Eq 23 kernels on cases with a closed form: with every beta zero the recursion is the straight line
z = z0 + A (x - x0), so where it crosses a divergence bound is known to the sample."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import FitScale, Problem, Samples
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS
from protocol_runner.models.bouc_wen.schemes import BoucWenShape, Integration, run_scheme
from protocol_runner.models.bouc_wen.simulation import simulate
from tests.models.sensitivity import simulate_sensitivity

LINE = BoucWenParams(A=1.0, n=1.0, beta=(0.0,) * 6)


def test_with_zero_betas_the_torque_is_a_line_of_slope_a() -> None:
    x = np.array([0.0, 1.0, 3.0, 2.0, -4.0, -4.0, 5.0])
    z = simulate(x, BoucWenParams(A=0.5, n=1.3, beta=(0.0,) * 6), z0=2.0, scheme="eq23")
    np.testing.assert_allclose(z, 2.0 + 0.5 * (x - x[0]), rtol=0, atol=1e-12)
    _, dz = simulate_sensitivity(x, BoucWenParams(A=0.5, n=1.3, beta=(0.0,) * 6), z0=2.0, scheme="eq23")
    np.testing.assert_allclose(dz[:, 0], x - x[0], atol=1e-12)  # d z / d A


def test_a_torque_reaching_the_bound_exactly_is_kept_and_the_next_one_diverges() -> None:
    x = np.arange(11.0)
    z = simulate(x, LINE, z0=0.0, bound_nm=5.0, scheme="eq23")
    np.testing.assert_array_equal(z[:6], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    assert np.all(np.isnan(z[6:]))


def test_the_fitter_holds_a_diverged_trial_at_the_bound_with_its_sign_and_restarts_the_next() -> None:
    # trial 1 falls through -5 at its 6th step, trial 2 rises gently from its own first torque
    x = np.concatenate([-np.arange(10.0), np.arange(6.0)])
    seg = np.array([0, 10, 16], dtype=np.int64)
    z0 = np.array([0.0, -2.0])
    z = np.empty_like(x)
    first_bad = run_scheme(x, seg, z0, BoucWenShape(1.0, 1.0, np.zeros(6)), Integration("eq23", 5.0), z)
    assert first_bad == 6
    np.testing.assert_array_equal(z[:6], [0.0, -1.0, -2.0, -3.0, -4.0, -5.0])
    np.testing.assert_array_equal(z[6:10], -5.0)
    np.testing.assert_array_equal(z[10:], [-2.0, -1.0, 0.0, 1.0, 2.0, 3.0])


def test_without_divergence_the_kernel_reports_none() -> None:
    x = np.arange(5.0)
    z = np.empty_like(x)
    assert (
        run_scheme(
            x,
            np.array([0, 5]),
            np.array([0.0]),
            BoucWenShape(1.0, 1.0, np.zeros(6)),
            Integration("eq23", 4.0),
            z,
        )
        == -1
    )
    assert z[-1] == pytest.approx(4.0)


def test_each_trial_starts_its_sensitivities_afresh() -> None:
    """Two trials in one pass give exactly the Jacobians of each trial alone: z0 is fixed, so every
    derivative is zero at a trial's first sample and nothing carries over from the trial before."""
    p = BoucWenParams(A=0.28, n=1.2, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.05))
    x1 = 50.0 * np.sin(np.linspace(0.0, 7.0, 150))
    x2 = 40.0 * np.sin(np.linspace(1.0, 9.0, 170))
    y1, y2 = simulate(x1, p, z0=1.0, scheme="eq23"), simulate(x2, p, z0=-2.0, scheme="eq23")

    def jac(x: np.ndarray, y: np.ndarray, seg: list[int]) -> np.ndarray:
        problem = Problem(Samples(x, y, np.array(seg, dtype=np.int64)), DEFAULT_BOUNDS, FitScale(50.0, 20.0))
        return problem.physical_jacobian(p.A, p.n, np.array(p.beta))

    joint = jac(np.concatenate([x1, x2]), np.concatenate([y1, y2]), [0, 150, 320])
    np.testing.assert_array_equal(joint[:150], jac(x1, y1, [0, 150]))
    np.testing.assert_array_equal(joint[150:], jac(x2, y2, [0, 170]))
    np.testing.assert_array_equal(joint[150], 0.0)


def test_the_first_divergence_is_reported_when_several_trials_diverge() -> None:
    x = np.concatenate([np.arange(10.0), np.arange(10.0)])
    seg = np.array([0, 10, 20], dtype=np.int64)
    z = np.empty_like(x)
    first_bad = run_scheme(
        x, seg, np.array([0.0, 2.0]), BoucWenShape(1.0, 1.0, np.zeros(6)), Integration("eq23", 5.0), z
    )
    assert first_bad == 6  # trial 2 diverges too (at sample 10 + 4), later
    np.testing.assert_array_equal(z[10:16], [2.0, 3.0, 4.0, 5.0, 5.0, 5.0])


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_a_state_held_below_one_newton_metre_keeps_its_sign(direction: float) -> None:
    """The straight line z = A x crosses a bound of 0.5 N*m at 0.6 (or -0.6) on 0.1 deg steps: the fitter
    holds it at +0.5 (or -0.5), the sign of the run-away, however small the bound."""
    x = direction * np.arange(0.0, 1.0, 0.1)
    z = np.empty_like(x)
    shape = BoucWenShape(LINE.A, LINE.n, np.array(LINE.beta))
    bad = run_scheme(x, np.array([0, x.size]), np.array([0.0]), shape, Integration("eq23", 0.5, True), z)
    assert bad == 6
    np.testing.assert_array_equal(z[6:], direction * 0.5)


def test_gram_is_the_normal_matrix_and_sum_sq_diff_the_squared_distance() -> None:
    """The Gauss-Newton normal matrix J^T J (symmetric, positive semi-definite) and ||z - y||^2, computed in
    compiled loops, equal numpy's."""
    from protocol_runner.models.bouc_wen.kernels import gram, sum_sq_diff

    rng = np.random.default_rng(3)
    J = rng.normal(size=(50, 8)) * np.array([1.0, 10.0, 0.1, 2.0, -3.0, 0.5, 7.0, 1e-3])
    G = gram(J)
    np.testing.assert_allclose(G, J.T @ J, rtol=1e-12, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(G) > -1e-9)
    z, y = rng.normal(size=40), rng.normal(size=40)
    assert sum_sq_diff(z, y) == pytest.approx(float(np.sum((z - y) ** 2)), rel=1e-13)
