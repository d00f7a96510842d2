"""Input checks of the analysis functions: clear user errors (exit status 2), never tracebacks."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.validation import AnalysisError, as_signal, same_length
from protocol_runner.errors import EXIT_INVALID_INPUT, InvalidInput, UserError


def test_analysis_error_is_an_invalid_input_with_exit_status_2() -> None:
    err = AnalysisError("x")
    assert isinstance(err, InvalidInput)
    assert isinstance(err, UserError)
    assert err.exit_code == EXIT_INVALID_INPUT


def test_as_signal_accepts_lists_and_returns_float64() -> None:
    out = as_signal("angle_deg", [1, 2, 3])
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0])


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (np.zeros((2, 3)), "1-D"),
        ([], "at least 1"),
        ([1.0, np.inf], "sample 1 is not a finite number"),
        (["a", "b"], "expected numbers"),
    ],
)
def test_as_signal_names_the_quantity_and_the_defect(values: object, message: str) -> None:
    with pytest.raises(AnalysisError, match=message) as info:
        as_signal("torque_nm", values)  # type: ignore[arg-type]
    assert str(info.value).startswith("torque_nm")


def test_same_length_lists_every_length() -> None:
    with pytest.raises(AnalysisError, match="a=2, b=3"):
        same_length(a=np.zeros(2), b=np.zeros(3))
    assert same_length(a=np.zeros(4), b=np.ones(4)) == 4
