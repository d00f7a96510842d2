"""Equal-time subtraction needs a brace-off clock that runs forward; one sample is a constant."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.subtraction import subtract_equal_time
from protocol_runner.analysis.validation import AnalysisError


def test_a_brace_off_clock_that_stalls_or_runs_back_is_refused() -> None:
    for t_off in ([0.0, 0.1, 0.1], [0.0, 0.2, 0.1], [0.2, 0.1]):
        with pytest.raises(AnalysisError, match="time_off_s must be strictly increasing"):
            subtract_equal_time([0.0, 0.1], [1.0, 1.0], t_off, np.arange(float(len(t_off))))


def test_a_single_brace_off_sample_is_subtracted_as_a_constant() -> None:
    out = subtract_equal_time([3.0, 3.1, 3.2], [5.0, 6.0, 7.0], [8.0], [2.0])
    np.testing.assert_allclose(out, [3.0, 4.0, 5.0])
