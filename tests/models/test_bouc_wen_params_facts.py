"""Facts of the Bouc-Wen parameters and the Table 4 phase algebra (thesis Eq 22-25), from Eq 23's sign
terms, not from the matrices the module holds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.params import (
    EQ24_PHASE_MATRIX,
    EQ25_BETA_MATRIX,
    PARAM_NAMES,
    BoucWenParams,
    betas_from_phases,
    phase_of_samples,
    phase_values,
)

# Table 4: phase k -> (sgn x, sgn dx, sgn z)
TABLE4 = {1: (1, 1, 1), 2: (1, -1, 1), 3: (1, -1, -1), 4: (-1, -1, -1), 5: (-1, 1, -1), 6: (-1, 1, 1)}
BETA = np.array([0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036])


def _eq23_psi(beta: np.ndarray, sx: int, sd: int, sz: int) -> float:
    """Eq 23: Psi = b1 sgn(dx z) + b2 sgn(dx x) + b3 sgn(x z) + b4 sgn(dx) + b5 sgn(z) + b6 sgn(x)."""
    terms = (sd * sz, sd * sx, sx * sz, sd, sz, sx)
    return float(sum(b * t for b, t in zip(beta, terms, strict=True)))


@pytest.mark.parametrize("k", range(1, 7))
def test_each_phase_value_is_eq23_evaluated_at_the_phase_signs(k: int) -> None:
    for beta in (BETA, np.eye(6)[k - 1], np.arange(1.0, 7.0)):
        assert phase_values(beta)[k - 1] == pytest.approx(_eq23_psi(beta, *TABLE4[k]), abs=1e-15)


def test_eq25_inverts_eq24() -> None:
    np.testing.assert_allclose(EQ25_BETA_MATRIX @ EQ24_PHASE_MATRIX, np.eye(6), atol=1e-15)
    np.testing.assert_allclose(EQ24_PHASE_MATRIX @ EQ25_BETA_MATRIX, np.eye(6), atol=1e-15)
    psi = np.array([0.4, -1.0, 2.5, 0.0, -57.0, 3.0])
    np.testing.assert_allclose(phase_values(betas_from_phases(psi)), psi, atol=1e-12)
    assert phase_values(BoucWenParams.from_phases(0.3, 1.2, psi).beta) == pytest.approx(psi)


def test_the_parameter_vector_is_in_the_named_order_and_round_trips() -> None:
    p = BoucWenParams(A=0.28, n=1.2, beta=tuple(BETA))
    v = p.as_array()
    assert PARAM_NAMES == ("A", "n", "beta1", "beta2", "beta3", "beta4", "beta5", "beta6")
    assert v[0] == 0.28 and v[1] == 1.2
    np.testing.assert_array_equal(v[2:], BETA)
    assert BoucWenParams.from_array(v) == p
    assert BoucWenParams.from_array(v.reshape(2, 4)) == p


@pytest.mark.parametrize("size", [7, 9, 0])
def test_a_vector_that_is_not_eight_numbers_is_invalid_input(size: int) -> None:
    with pytest.raises(InvalidInput, match="8 entries"):
        BoucWenParams.from_array(np.ones(size))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"A": 1.0, "n": 0.0, "beta": (0.0,) * 6}, "positive"),
        ({"A": 1.0, "n": -1.0, "beta": (0.0,) * 6}, "positive"),
        ({"A": math.nan, "n": 1.0, "beta": (0.0,) * 6}, "finite"),
        ({"A": 1.0, "n": math.inf, "beta": (0.0,) * 6}, "finite"),
        ({"A": 1.0, "n": 1.0, "beta": (0.0, 0.0, 0.0, 0.0, 0.0, math.inf)}, "finite"),
        ({"A": 1.0, "n": 1.0, "beta": (0.0,) * 5}, "exactly 6"),
        ({"A": 1.0, "n": 1.0, "beta": (0.0,) * 7}, "exactly 6"),
    ],
)
def test_parameters_outside_the_model_are_invalid_input(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        BoucWenParams(**kwargs)


def test_a_tiny_positive_exponent_is_a_model() -> None:
    assert BoucWenParams(A=0.0, n=1e-9, beta=(0.0,) * 6).n == 1e-9


def test_each_step_gets_the_table4_phase_of_its_signs_and_others_get_zero() -> None:
    """Step i -> i+1 has the phase of (sgn x_i, sgn(x_{i+1} - x_i), sgn z_i)."""
    for k, (sx, sd, sz) in TABLE4.items():
        x = np.array([2.0 * sx, 2.0 * sx + sd])
        z = np.array([3.0 * sz, 0.0])
        assert phase_of_samples(x, z).tolist() == [k]
    # the two sign patterns outside Table 4, and a zero sign of each kind
    for x, z in (([1.0, 2.0], [-1.0, 0.0]), ([-1.0, -2.0], [1.0, 0.0])):
        assert phase_of_samples(np.array(x), np.array(z)).tolist() == [0]
    for x, z in (([0.0, 1.0], [1.0, 1.0]), ([1.0, 1.0], [1.0, 1.0]), ([1.0, 2.0], [0.0, 1.0])):
        assert phase_of_samples(np.array(x), np.array(z)).tolist() == [0]


def test_a_path_returns_one_phase_per_step() -> None:
    x = np.array([1.0, 2.0, 1.0, -1.0, -2.0, -1.0, 1.0])
    z = np.array([1.0, 1.0, -1.0, -1.0, -1.0, 1.0, 1.0])
    assert phase_of_samples(x, z).tolist() == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("x, z", [(np.zeros((2, 3)), np.zeros((2, 3))), (np.zeros(4), np.zeros(3))])
def test_phase_of_samples_needs_two_1d_arrays_of_one_length(x: np.ndarray, z: np.ndarray) -> None:
    with pytest.raises(InvalidInput, match="two 1-D arrays"):
        phase_of_samples(x, z)
