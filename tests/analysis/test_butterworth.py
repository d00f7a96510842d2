"""The session's scipy-free Butterworth low-pass (`analysis/butterworth.py`) is bit for bit the filter
`analysis/filters.py` makes with scipy: the design, the start-up state and the zero-phase pass."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from protocol_runner.analysis.butterworth import butterworth_sos, padding, sections_zi, zero_phase
from protocol_runner.analysis.filters import design_lowpass, filter_zero_phase_together, lowpass
from protocol_runner.analysis.validation import AnalysisError

CUTOFFS = [
    0.002,
    0.01,
    5.0 / 500.0,
    5.0 / 250.0,
    0.1,
    0.37,
    0.5,
    0.9,
    *np.random.default_rng(7).uniform(0.001, 0.95, 25),
]


@pytest.mark.parametrize("order", [2, 4, 6, 8, 10])
def test_the_design_and_its_start_up_state_are_scipys_bit_for_bit(order: int) -> None:
    for cutoff in CUTOFFS:
        sos = butterworth_sos(order, float(cutoff))
        assert np.array_equal(sos, design_lowpass("butterworth", order, float(cutoff))), cutoff
        assert np.array_equal(sections_zi(sos), signal.sosfilt_zi(sos)), cutoff


def test_the_zero_phase_pass_is_lowpass_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    for _ in range(30):
        order = int(rng.choice([2, 4, 6, 8]))
        cutoff = float(rng.uniform(0.002, 0.6))
        n = int(rng.integers(3 * (order + 1) + 1, 70_000))
        x = np.cumsum(rng.standard_normal(n)) + rng.uniform(-100, 100)
        sos = butterworth_sos(order, cutoff)
        expected = signal.sosfiltfilt(sos, x, padtype="odd", padlen=padding(sos))  # scipy's own pass
        assert np.array_equal(lowpass(x, kind="butterworth", order=order, cutoff=cutoff), expected)
        assert np.array_equal(zero_phase(x, sos), expected), (order, cutoff, n)


@pytest.mark.parametrize("kind", ["butterworth", "chebyshev"])
def test_the_analysis_pass_is_scipys_sosfiltfilt_bit_for_bit_for_every_design(kind: str) -> None:
    """The analysis's filter (`filters.filter_zero_phase_together`, through `zero_phase_pass`) against
    scipy's `sosfilt_zi` and `sosfiltfilt`, for both kinds, odd orders too (a first-order section), and
    signals of several scales and dtypes filtered together."""
    rng = np.random.default_rng(12)
    for _ in range(25):
        order = int(rng.integers(1, 13))
        cutoff = float(rng.uniform(0.005, 0.8))
        sos = design_lowpass(kind, order, cutoff, float(rng.uniform(0.1, 3.0)))
        assert np.array_equal(sections_zi(sos), signal.sosfilt_zi(sos)), (kind, order, cutoff)
        n = int(rng.integers(padding(sos) + 1, 40_000))
        angle = np.cumsum(rng.standard_normal(n)) * rng.uniform(0.01, 10.0) + rng.uniform(-100, 100)
        torque = (rng.standard_normal(n) * 20.0).astype(np.float32)
        got = filter_zero_phase_together([angle, torque], sos, names=["angle", "torque"])
        for mine, x in zip(got, (angle, torque), strict=True):
            expected = signal.sosfiltfilt(sos, x.astype(np.float64), padtype="odd", padlen=padding(sos))
            assert np.array_equal(mine, expected), (kind, order, cutoff, n)
            assert mine.dtype == np.float64 and mine.flags.c_contiguous


def test_sections_that_are_not_a_filter_are_refused() -> None:
    with pytest.raises(AnalysisError, match="second-order sections"):
        filter_zero_phase_together([np.zeros(500)], np.ones((2, 5)), names=["angle"])
    with pytest.raises(AnalysisError, match=r"section 0 has 2\.0"):
        filter_zero_phase_together([np.zeros(500)], 2.0 * design_lowpass(), names=["angle"])


def test_a_constant_passes_unchanged_and_a_fast_wiggle_is_removed() -> None:
    sos = butterworth_sos(4, 0.01)
    assert np.allclose(zero_phase(np.full(3000, 42.5), sos), 42.5, rtol=0, atol=1e-9)
    t = np.arange(20_000) / 1000.0
    slow, fast = 30.0 * np.sin(2 * np.pi * 0.3 * t), 2.0 * np.sin(2 * np.pi * 60.0 * t)
    out = zero_phase(slow + fast, sos)
    assert np.max(np.abs(out - slow)[1000:-1000]) < 0.05  # 60 Hz far above the 5 Hz cut-off, no lag


def test_what_it_does_not_make_is_refused_with_the_reason() -> None:
    for order in (3, 0, 2.5):
        with pytest.raises(AnalysisError, match="even order"):
            butterworth_sos(order, 0.1)  # type: ignore[arg-type]
    for cutoff in (0.0, 1.0, -0.2):
        with pytest.raises(AnalysisError, match="cut-off"):
            butterworth_sos(4, cutoff)
    sos = butterworth_sos(4, 0.1)
    with pytest.raises(AnalysisError, match="too few"):
        zero_phase(np.zeros(padding(sos)), sos, name="angle")


def test_the_t_quantiles_and_tails_are_scipy_stats_bit_for_bit() -> None:
    """`analysis.statistics` takes Student's t from scipy.special: the numbers of scipy.stats.t."""
    from scipy import stats

    from protocol_runner.analysis.statistics import t_quantile, t_sf

    rng = np.random.default_rng(9)
    for dof in [1.0, 2.0, 3.5, 7.0, 29.0, 1e3, float("inf"), float("nan"), 0.0, *rng.uniform(0.5, 200, 40)]:
        for q in (0.5, 0.9, 0.975, 0.995):
            assert np.array_equal(t_quantile(q, dof), float(stats.t.ppf(q, dof)), equal_nan=True)
        for x in (0.0, 0.3, 2.0, 11.0):
            assert np.array_equal(t_sf(x, dof), float(stats.t.sf(x, dof)), equal_nan=True)
