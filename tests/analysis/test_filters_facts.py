"""Filter defaults are the thesis's (10th-order Butterworth at 10 % of Nyquist, §3.2) and the design
accepts any whole-number order while refusing what is not a low-pass filter."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from protocol_runner.analysis.filters import design_lowpass, filter_zero_phase, lowpass
from protocol_runner.analysis.validation import AnalysisError


def test_the_default_filter_is_the_thesis_10th_order_butterworth_at_a_tenth_of_nyquist() -> None:
    x = np.random.default_rng(2).normal(0.0, 1.0, 3000)
    expected = signal.sosfiltfilt(signal.butter(10, 0.1, output="sos"), x, padtype="odd", padlen=33)
    np.testing.assert_allclose(lowpass(x), expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(design_lowpass(), signal.butter(10, 0.1, output="sos"), rtol=1e-12, atol=1e-15)


def test_a_whole_number_order_of_any_numeric_type_gives_the_same_filter() -> None:
    # the float first, at a cut-off no other test designs: designs are cached by value, and 3.0 == 3
    as_float = design_lowpass("butterworth", 3.0, 0.2371)  # type: ignore[arg-type]
    reference = design_lowpass("butterworth", 3, 0.2371)
    np.testing.assert_array_equal(as_float, reference)
    np.testing.assert_array_equal(design_lowpass("butterworth", np.int64(3), 0.2371), reference)  # type: ignore[arg-type]
    with pytest.raises(AnalysisError, match="whole number"):
        design_lowpass("butterworth", True, 0.2)  # type: ignore[arg-type]


def test_a_negative_cutoff_is_a_user_error() -> None:
    with pytest.raises(AnalysisError, match="strictly between 0 and 1"):
        design_lowpass("butterworth", 4, -0.1)


def test_a_signal_far_shorter_than_the_padding_is_a_user_error() -> None:
    sos = design_lowpass("butterworth", 10, 0.1)
    with pytest.raises(AnalysisError, match="5 samples are too few"):
        filter_zero_phase(np.ones(5), sos, name="angle_deg")
