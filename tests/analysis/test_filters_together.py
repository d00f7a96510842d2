"""Filtering several signals together (analysis/filters.py `filter_zero_phase_together`) gives each exactly
what filtering it alone gives; sections that are not a filter are refused with the reason; the brace-off
command smoothing (4th order, a cut-off of 1 % of Nyquist) keeps a constant and removes a fast wiggle
without lag."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.filters import (
    design_lowpass,
    filter_zero_phase,
    filter_zero_phase_together,
    lowpass,
)
from protocol_runner.analysis.validation import AnalysisError


@pytest.mark.parametrize("kind", ["butterworth", "chebyshev"])
def test_each_signal_is_bit_for_bit_its_own_filtering(kind: str) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(5000) / 1000.0
    angle = 50.0 + 40.0 * np.sin(2 * np.pi * 0.4 * t) + rng.normal(0.0, 0.2, t.size)
    torque = (10.0 * np.cos(2 * np.pi * 0.4 * t) + rng.normal(0.0, 1.0, t.size)).astype(np.float32)
    sos = design_lowpass(kind, 10, 0.1)
    together = filter_zero_phase_together([angle, torque], sos, names=["angle", "torque"])
    assert np.array_equal(together[0], filter_zero_phase(angle, sos))
    assert np.array_equal(together[1], filter_zero_phase(torque, sos))
    assert together[0].dtype == np.float64 and together[0].flags.c_contiguous


def test_signals_of_different_lengths_are_refused_by_name() -> None:
    sos = design_lowpass()
    with pytest.raises(AnalysisError, match="angle, torque must have the same length"):
        filter_zero_phase_together([np.zeros(500), np.zeros(400)], sos, names=["angle", "torque"])
    with pytest.raises(AnalysisError, match="torque: 10 samples are too few"):
        filter_zero_phase_together([np.zeros(500), np.zeros(10)], sos, names=["angle", "torque"])


def test_sections_that_are_not_a_filter_are_refused() -> None:
    for columns in (5, 7):  # a section is six coefficients, b0 b1 b2 1 a1 a2
        with pytest.raises(AnalysisError, match="second-order sections"):
            filter_zero_phase_together([np.zeros(500)], np.ones((2, columns)), names=["angle"])
    for a0 in (2.0, 0.5):  # not normalised, either way: the first such section is named
        sections = design_lowpass()
        sections[1] *= a0
        with pytest.raises(AnalysisError, match=f"section 1 has {a0}"):
            filter_zero_phase_together([np.zeros(500)], sections, names=["angle"])


def test_a_constant_passes_unchanged_and_a_fast_wiggle_is_removed() -> None:
    assert np.allclose(lowpass(np.full(3000, 42.5), order=4, cutoff=0.01), 42.5, rtol=0, atol=1e-9)
    t = np.arange(20_000) / 1000.0
    slow, fast = 30.0 * np.sin(2 * np.pi * 0.3 * t), 2.0 * np.sin(2 * np.pi * 60.0 * t)
    out = lowpass(slow + fast, order=4, cutoff=0.01)
    assert np.max(np.abs(out - slow)[1000:-1000]) < 0.05  # 60 Hz far above the 5 Hz cut-off, no lag
