"""Brace-off scaling over the cycles (thesis §3.3.2 Eq 8-9) and the inverted servo lag (§2.4.2)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.scaling import cycle_range, lag_input, scale_brace_off_input

from .synth import first_order_lag

RATE_HZ = 100.0


def _triangle(n_cycles: int = 4) -> np.ndarray:
    t = np.arange(0.0, n_cycles * 6.0, 1.0 / RATE_HZ)
    return 50.0 + 30.0 * (2.0 / np.pi) * np.arcsin(np.sin(2.0 * np.pi * t / 6.0 - np.pi / 2.0))


def test_cycle_range_is_the_mean_of_the_turning_points_not_the_approach() -> None:
    angle = _triangle()
    angle[:50] = np.linspace(0.0, angle[50], 50)  # arriving from a park angle far below the cycles
    lo, hi = cycle_range(angle)
    assert lo == pytest.approx(20.0, abs=0.05) and hi == pytest.approx(80.0, abs=0.05)
    assert float(angle.min()) == 0.0  # what the extremes would have said


def test_a_first_order_lag_driven_by_lag_input_returns_the_wanted_output() -> None:
    t = np.arange(0.0, 20.0, 1.0 / RATE_HZ)
    wanted = 50.0 + 30.0 * np.sin(2.0 * np.pi * t / 5.0)
    out = first_order_lag(lag_input(t, wanted, 0.2), 1.0 / RATE_HZ, 0.2, wanted[0])
    assert np.max(np.abs(out - wanted)) < 0.25  # the hold of the 100 Hz samples: half a tick behind
    # fed the wanted output itself, the lag attenuates and delays it by degrees
    assert np.max(np.abs(first_order_lag(wanted, 1.0 / RATE_HZ, 0.2, wanted[0]) - wanted)) > 5.0


def test_a_run_arriving_low_is_scaled_on_its_cycles() -> None:
    """The brace-off run starts 8 deg below its cycles (a lagging approach): matching its first sample would
    stop the loops short; matching the turning points brings both cycle levels within 0.1 deg."""
    target = (20.0, 80.0)

    def plant(u: np.ndarray) -> np.ndarray:
        out = 0.95 * first_order_lag(u, 1.0 / RATE_HZ, 0.2, u[0] - 8.0) + 1.0
        return out

    result = scale_brace_off_input(_triangle(), target, plant, max_iterations=6)
    assert result.converged and result.best.range_error_deg <= 0.1
    lo, hi = cycle_range(plant(result.input_deg))
    assert lo == pytest.approx(20.0, abs=0.1) and hi == pytest.approx(80.0, abs=0.1)
