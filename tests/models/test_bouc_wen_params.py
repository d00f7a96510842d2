"""BoucWenParams refuses what is not eight numbers with a clear InvalidInput, never a TypeError."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.params import BoucWenParams, betas_from_phases, phase_values

NOT_A_NUMBER: Any = "stiff"
NOT_A_SEQUENCE: Any = 3.0


@pytest.mark.parametrize(
    "kwargs",
    [
        {"A": NOT_A_NUMBER, "n": 1.0, "beta": (0.0,) * 6},  # ValueError inside float()
        {"A": None, "n": 1.0, "beta": (0.0,) * 6},  # TypeError inside float()
        {"A": 1.0, "n": 1.0, "beta": NOT_A_SEQUENCE},  # TypeError: not iterable
    ],
)
def test_parameters_that_are_not_numbers_are_invalid_input(kwargs: dict) -> None:
    with pytest.raises(InvalidInput, match="needs numbers"):
        BoucWenParams(**kwargs)


@pytest.mark.parametrize("values", [np.zeros(5), np.zeros(7), np.zeros((6, 1)), np.zeros((1, 6))])
def test_the_phase_algebra_takes_exactly_six_values(values: np.ndarray) -> None:
    with pytest.raises(InvalidInput, match="the 6 betas"):
        phase_values(values)
    with pytest.raises(InvalidInput, match="the 6 phase values"):
        betas_from_phases(values)
