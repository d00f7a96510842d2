"""Boundaries of the analysis input checks: exactly `min_length` samples pass, a scalar is not a signal, and
the message names the first bad sample."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.validation import AnalysisError, as_signal


def test_a_single_number_is_not_a_signal() -> None:
    with pytest.raises(AnalysisError, match="1-D"):
        as_signal("angle_deg", 3.0)


def test_exactly_min_length_samples_are_enough() -> None:
    assert as_signal("torque_nm", [1.0, 2.0], min_length=2).shape == (2,)
    with pytest.raises(AnalysisError, match="needs at least 3 samples, got 2"):
        as_signal("torque_nm", [1.0, 2.0], min_length=3)


def test_the_first_non_finite_sample_is_named() -> None:
    with pytest.raises(AnalysisError, match=r"sample 1 is not a finite number \(nan\)"):
        as_signal("torque_nm", [0.0, np.nan, 2.0, np.inf])
    assert np.isnan(as_signal("torque_nm", [0.0, np.nan], allow_nan=True)[1])
