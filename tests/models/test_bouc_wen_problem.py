"""The fit's bounds are relative to the data (BoucWenBounds): a = A X / Z, n, psi' = psi X Z^(n-1); a
bound that excludes the true model holds the fitted value at the bound in physical units."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.fitting import fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams, phase_values
from protocol_runner.models.bouc_wen.problem import FitScale, Problem, Samples
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS, BoucWenBounds
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _loop() -> tuple[np.ndarray, np.ndarray]:
    x = 60.0 * np.sin(2 * np.pi * np.arange(240) / 160.0)
    return x, simulate(x, FIG57, z0=0.0)


def test_dimensionless_parameters_round_trip_to_physical_ones() -> None:
    x, y = _loop()
    X, Z = 60.0, 20.0
    problem = Problem(Samples(x, y, np.array([0, x.size])), BoucWenBounds(), FitScale(X, Z))
    u = problem.to_u(FIG57)
    assert u[0] == pytest.approx(FIG57.A * X / Z)
    assert u[1] == FIG57.n
    np.testing.assert_allclose(u[2:], phase_values(FIG57.beta) * X * Z ** (FIG57.n - 1.0))
    np.testing.assert_allclose(problem.params(u).as_array(), FIG57.as_array(), rtol=1e-12)


def test_bounds_are_the_dimensionless_box() -> None:
    b = BoucWenBounds(a_max=7.0, n_min=0.8, n_max=2.5, psi_max=30.0)
    np.testing.assert_array_equal(b.lower(), [0.0, 0.8, *([-30.0] * 6)])
    np.testing.assert_array_equal(b.upper(), [7.0, 2.5, *([30.0] * 6)])


def test_a_bound_below_the_truth_holds_the_fit_at_the_bound() -> None:
    x, y = _loop()
    X, Z = float(np.max(np.abs(x))), float(np.max(np.abs(y)))
    capped_n = fit_trials([(x, y)], starts=2, bounds=BoucWenBounds(n_max=1.0))
    assert capped_n.params.n == pytest.approx(1.0)
    a_cap = 0.5 * FIG57.A * X / Z  # half the true dimensionless slope
    capped_a = fit_trials([(x, y)], starts=2, bounds=BoucWenBounds(a_max=a_cap))
    fitted_slope = capped_a.params.A
    assert fitted_slope == pytest.approx(a_cap * Z / X)
    assert capped_a.angle_scale_deg == X and capped_a.torque_scale_nm == Z


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"a_max": 0.0}, "a_max"),
        ({"a_max": float("inf")}, "a_max"),
        ({"n_min": 2.0, "n_max": 2.0}, "n_min < n_max"),
        ({"n_min": 0.0}, "n_min < n_max"),
        ({"n_min": -1.0}, "n_min < n_max"),
        ({"n_min": 3.0, "n_max": 2.0}, "n_min < n_max"),
        ({"a_max": -1.0}, "a_max"),
        ({"psi_max": -1.0}, "psi_max"),
        ({"n_max": float("inf")}, "n_min < n_max"),
        ({"psi_max": 0.0}, "psi_max"),
        ({"psi_max": float("inf")}, "psi_max"),
    ],
)
def test_bounds_that_enclose_nothing_are_invalid_input(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        BoucWenBounds(**kwargs)


def test_the_default_bounds_are_the_documented_ones() -> None:
    # BoucWenBounds docstring: 0 <= a <= 20, 0.5 <= n <= 3, |psi'| <= 100; Figure 57 on a +-65 deg,
    # 20 N m loop has psi'_5 = -57, well inside
    np.testing.assert_array_equal(DEFAULT_BOUNDS.lower(), [0.0, 0.5, *([-100.0] * 6)])
    np.testing.assert_array_equal(DEFAULT_BOUNDS.upper(), [20.0, 3.0, *([100.0] * 6)])
    x, y = _loop()
    problem = Problem(Samples(x, y, np.array([0, x.size])), DEFAULT_BOUNDS, FitScale(65.0, 20.0))
    assert problem.to_u(FIG57)[2 + 4] == pytest.approx(-57.0, abs=0.5)


def test_a_diverging_start_is_pulled_toward_the_straight_line_until_it_stays_bounded() -> None:
    """Problem.stabilise: halve the distance to a = 1, psi' = 0 (a line of the loop's mean slope) until the
    recursion no longer passes 10 x the torque scale, where the fitter holds it (a finite penalty)."""
    x, y = _loop()
    Z = float(np.max(np.abs(y)))
    problem = Problem(Samples(x, y, np.array([0, x.size])), DEFAULT_BOUNDS, FitScale(60.0, Z))
    assert problem.bound == 10.0 * Z
    unstable = BoucWenParams(A=0.3, n=2.0, beta=(0.0, 0.0, 0.0, 0.0, 0.0, -1.0))
    u_bad = problem.to_u(unstable)
    r = problem.residuals(u_bad)
    k = problem.diverged_at
    assert k > 0
    np.testing.assert_allclose(r[k:] * Z + y[k:], np.sign(r[k] * Z + y[k]) * 10.0 * Z)
    J = problem.jacobian(u_bad)
    assert np.all(J[k:] == 0.0) and np.any(J[:k] != 0.0)  # the held penalty does not move with the parameters
    v = problem.stabilise(u_bad)
    problem.residuals(v)
    assert problem.diverged_at == -1
    centre = u_bad.copy()
    centre[0] = 1.0
    centre[2:] = 0.0
    steps = np.log2(np.linalg.norm(u_bad - centre) / np.linalg.norm(v - centre))
    assert steps == pytest.approx(round(steps)) and round(steps) >= 1  # a whole number of halvings
    np.testing.assert_allclose(v - centre, (u_bad - centre) / 2.0 ** round(steps))
