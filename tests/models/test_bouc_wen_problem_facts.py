"""Facts of the Bouc-Wen least-squares problem (problem.py, thesis §6.2.3): its Jacobian is the derivative of
its residuals in the dimensionless parameters (fused with a residual evaluation or not), its RMSE is that
of its residuals in N*m, and the neutral point a start is pulled toward is a = 1 inside the bounds."""

from __future__ import annotations

import math

import numpy as np

from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import (
    FitScale,
    Problem,
    Samples,
    evaluate,
    jacobian_std,
    param_std,
    trial_torques,
)
from protocol_runner.models.bouc_wen.records import BoucWenBounds
from protocol_runner.models.bouc_wen.simulation import simulate
from tests.models.sensitivity import simulate_sensitivity

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _problem(scheme: str = "eq23", bounds: BoucWenBounds | None = None) -> Problem:
    x = 60.0 * np.sin(2 * np.pi * np.arange(200) / 160.0)
    y = simulate(x, FIG57, z0=0.0, scheme="eq23") + 0.3 * np.cos(np.arange(200) / 7.0)
    scale = FitScale(float(np.max(np.abs(x))), float(np.max(np.abs(y))))
    return Problem(Samples(x, y, np.array([0, x.size])), bounds or BoucWenBounds(), scale, scheme)


def _finite_difference(problem: Problem, u: np.ndarray) -> np.ndarray:
    cols = []
    for k in range(8):
        h = 1e-6 * max(1.0, abs(u[k]))
        up, down = u.copy(), u.copy()
        up[k] += h
        down[k] -= h
        cols.append((problem.residuals(up) - problem.residuals(down)) / (2 * h))
    return np.column_stack(cols)


def test_the_jacobian_is_the_derivative_of_the_residuals_fused_or_not() -> None:
    """Eq 23 residuals (z - y) / Z in u = (a, n, psi'_1..6): the analytic Jacobian (chain rule through
    Eq 25 and the data scales) equals central differences, whether it is computed on its own or taken from
    the residual evaluation of a solve at the same point."""
    problem = _problem()
    u = problem.to_u(BoucWenParams(A=0.3, n=1.1, beta=(0.01, 0.12, -0.1, -0.08, 0.09, -0.01)))
    numeric = _finite_difference(problem, u)
    alone = problem.jacobian(u)
    np.testing.assert_allclose(alone, numeric, rtol=1e-4, atol=1e-7 * np.max(np.abs(numeric)))
    problem.fused = True
    problem.residuals(u)
    fused = problem.jacobian(u)
    problem.fused = False
    np.testing.assert_allclose(fused, alone, rtol=1e-12, atol=0.0)


def test_the_rmse_of_a_cost_is_that_of_the_residuals_in_newton_metres() -> None:
    problem = _problem()
    u = problem.to_u(BoucWenParams(A=0.3, n=1.1, beta=(0.0,) * 6))
    r = problem.residuals(u)
    direct = math.sqrt(float(np.mean((problem.z - problem.y) ** 2)))
    assert math.isclose(problem.rmse(problem.cost(u)), direct, rel_tol=1e-12)
    assert math.isclose(direct, math.sqrt(float(np.mean(r**2))) * problem.Z, rel_tol=1e-12)


def test_a_diverging_start_is_pulled_toward_a_equal_one_clipped_into_the_bounds() -> None:
    """The neutral point is the straight line of the loop's mean slope, a = 1 and psi' = 0, with n kept;
    with a_max below 1 it is a = a_max. A start far into divergence ends (after the halvings) close to it."""
    for a_max, a_neutral in ((20.0, 1.0), (0.6, 0.6)):
        problem = _problem(bounds=BoucWenBounds(a_max=a_max))
        wild = np.array([a_max, 1.7, *([-problem.bounds.psi_max] * 6)])
        v = problem.stabilise(wild)
        assert problem.diverged_at < 0
        assert v[1] == 1.7  # n is not moved
        halvings = math.log2((a_max - a_neutral) / (v[0] - a_neutral)) if v[0] != a_neutral else None
        direction = (v[2:] - 0.0) / (wild[2:] - 0.0)
        np.testing.assert_allclose(direction, direction[0])  # psi' shrinks toward 0 by one factor
        if halvings is not None:
            assert math.isclose(
                halvings, math.log2(1.0 / direction[0]), rel_tol=1e-9
            )  # a moved toward a_neutral by the same factor


def test_each_trial_is_evaluated_from_its_own_first_torque() -> None:
    """The parameters that made two trials, each started at its own torque, reproduce them exactly: zero
    error, R^2 = 1, no divergence."""
    x = 60.0 * np.sin(2 * np.pi * np.arange(200) / 160.0)
    segments = [(x, simulate(x, FIG57, z0=5.0)), (x[::-1].copy(), simulate(x[::-1], FIG57, z0=-3.0))]
    rmse, r2, per, diverged = evaluate(segments, FIG57, 1e3)
    assert rmse < 1e-12 and per[0] < 1e-12 and per[1] < 1e-12
    assert r2 == 1.0 and not diverged


def test_a_diverging_trial_is_evaluated_with_a_finite_error_at_the_bound() -> None:
    """Diverged samples are held at +-bound: the error is finite (and large), the trial flagged."""
    x = 60.0 * np.sin(2 * np.pi * np.arange(200) / 160.0)
    unstable = BoucWenParams(A=0.5, n=1.5, beta=(0.0, 0.0, 0.0, 0.0, -2.0, 0.0))
    y = simulate(x, FIG57, z0=0.0)
    rmse, _, per, diverged = evaluate([(x, y)], unstable, 100.0)
    assert diverged
    assert math.isfinite(rmse) and rmse > 10.0 and per[0] == rmse


def test_parameter_uncertainties_of_a_decimated_fit_are_those_of_its_compared_samples() -> None:
    """With residuals at every second sample only, param_std is the least-squares covariance of those
    samples: sqrt(diag(s^2 (J^T J)^-1)) with J and the residuals taken at the compared rows."""
    x = 60.0 * np.sin(2 * np.pi * np.arange(200) / 160.0)
    y = simulate(x, FIG57, z0=0.0) + 0.3 * np.cos(np.arange(200) / 7.0)
    rows = np.arange(0, 200, 2, dtype=np.int64)
    scale = FitScale(60.0, float(np.max(np.abs(y))))
    problem = Problem(Samples(x, y, np.array([0, 200]), rows), BoucWenBounds(), scale)
    z, dz = simulate_sensitivity(x, FIG57, z0=y[0])
    expected = jacobian_std(dz[rows], float(np.sum((z[rows] - y[rows]) ** 2)))
    np.testing.assert_allclose(param_std(problem, FIG57), expected, rtol=1e-9)


def test_two_parameters_that_act_alike_are_both_undetermined() -> None:
    """Columns 3 and 4 of the Jacobian equal: only their sum is determined, so both get an infinite
    uncertainty; the other six, independent, stay finite."""
    rng = np.random.default_rng(2)
    J = rng.normal(size=(50, 8))
    J[:, 4] = J[:, 3]
    std = jacobian_std(J, 1.0)
    assert np.isinf(std[3]) and np.isinf(std[4])
    assert np.all(np.isfinite(np.delete(std, [3, 4])))


def test_every_residual_evaluation_counts_once_fused_or_not() -> None:
    """nfev (the fit record's count of residual evaluations) grows by one per evaluation, whether or not
    the evaluation also gives the Jacobian."""
    problem = _problem()
    u = problem.to_u(FIG57)
    problem.residuals(u)
    problem.fused = True
    problem.residuals(u)
    problem.fused = False
    problem.cost(u)
    assert problem.nfev == 3


def test_the_last_integration_is_handed_back_only_for_exactly_its_trials() -> None:
    """trial_torques: after the problem integrated two trials at the Figure 57 parameters, each trial's
    torque is `simulate`'s from its first torque; any other set of trials gets None (one fewer,
    one more, a lower first torque: another recursion), as does another scheme."""
    x = 60.0 * np.sin(2 * np.pi * np.arange(200) / 160.0)
    trials = [(x, simulate(x, FIG57, z0=z0)) for z0 in (0.0, 2.0)]
    xs, ys = np.concatenate([x, x]), np.concatenate([y for _, y in trials])
    scale = FitScale(60.0, float(np.max(np.abs(ys))))
    problem = Problem(Samples(xs, ys, np.array([0, 200, 400])), BoucWenBounds(), scale, "refined")
    problem.residuals(problem.to_u(FIG57))
    torques = trial_torques(problem, trials, "refined")
    assert torques is not None
    for torque, (_, y) in zip(torques, trials, strict=True):
        np.testing.assert_allclose(torque, y, rtol=0.0, atol=1e-9)  # the parameters went through to_u
    lowered = [(x, y.copy()) for x, y in trials]
    lowered[-1][1][0] -= 0.5
    for other in (trials[:-1], trials + trials[:1], lowered):
        assert trial_torques(problem, other, "refined") is None
    assert trial_torques(problem, trials, "eq23") is None
