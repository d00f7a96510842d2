"""Complete-cycle identification (thesis §5.7.1): upward crossings of the mean angle, with hysteresis."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from protocol_runner.analysis.cycles import complete_cycles, reference_level, upward_crossings
from protocol_runner.analysis.validation import AnalysisError


def _angle(periods: float, start_phase: float, n_per_period: int = 1000) -> np.ndarray:
    phase = start_phase + 2 * np.pi * np.arange(int(periods * n_per_period)) / n_per_period
    return 60.0 + 45.0 * np.sin(phase)


@pytest.mark.parametrize(("periods", "start_phase"), [(5.0, 0.3), (5.5, 2.0), (6.25, 4.0), (3.9, 5.5)])
def test_only_complete_cycles_are_returned(periods: float, start_phase: float) -> None:
    angle = _angle(periods, start_phase)
    ref = angle.mean()
    cycles = complete_cycles(angle)
    # upward crossings of the mean happen where the phase passes a multiple of 2 pi (mean ~ 60)
    first_up = int(np.ceil(start_phase / (2 * np.pi)))
    last_phase = start_phase + 2 * np.pi * periods
    n_ups = int(np.floor(last_phase / (2 * np.pi))) - first_up + 1
    assert len(cycles) == n_ups - 1
    for s, e in cycles:
        assert angle[s - 1] < ref <= angle[s]
        assert angle[e - 1] < ref <= angle[e]
        assert e - s == pytest.approx(1000, abs=2)
    assert all(e1 == s2 for (_, e1), (s2, _) in itertools.pairwise(cycles))


def test_noise_does_not_create_extra_cycles() -> None:
    angle = _angle(6.0, 1.0)
    noisy = angle + np.random.default_rng(0).normal(0.0, 1.0, angle.shape)
    assert len(complete_cycles(noisy)) == len(complete_cycles(angle)) == 5
    # without hysteresis the same noise would be counted as many crossings: the hysteresis matters
    assert len(complete_cycles(noisy, hysteresis_deg=0.0)) > 20


def test_small_wiggles_that_do_not_clear_the_hysteresis_are_ignored() -> None:
    t = np.linspace(0.0, 1.0, 1001)
    # one big cycle, then a small oscillation around the mean that never leaves the +-5 deg band
    big = 50.0 + 40.0 * np.sin(2 * np.pi * 2 * t)
    big[600:] = 50.0 + 3.0 * np.sin(2 * np.pi * 30 * t[600:])
    ups = upward_crossings(big, hysteresis_deg=5.0, reference="mean")
    assert ups.size == 1


def test_linear_reference_follows_a_drifting_angle() -> None:
    n = 8000
    k = np.arange(n)
    angle = 20.0 + 0.01 * k + 10.0 * np.sin(2 * np.pi * k / 1000 + 0.5)  # drift of 80 deg over 8 cycles
    level = reference_level(angle, "linear")
    np.testing.assert_allclose(np.diff(level), np.diff(level)[0])  # a straight line
    assert len(complete_cycles(angle, reference="linear")) == 7
    assert len(complete_cycles(angle, reference="mean")) < 7  # the mean misses cycles of a drifting trial


def test_no_complete_cycle_in_less_than_one_period() -> None:
    assert complete_cycles(_angle(0.9, 0.0)) == []


def test_bad_reference_and_hysteresis_are_rejected() -> None:
    with pytest.raises(AnalysisError, match="unknown cycle reference"):
        reference_level(np.zeros(4), "median")  # type: ignore[arg-type]
    with pytest.raises(AnalysisError, match="must not be negative"):
        upward_crossings(_angle(2, 0), hysteresis_deg=-1.0)
