"""The calibration check's first-order model and time-constant search without scipy
(`analysis/step_response.py`): the response is scipy's `lfilter` recursion bit for bit; the time constant
lies within 1e-4 s of what scipy's bounded search (tolerance 1e-4 s) found before (docs/analysis.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from protocol_runner.analysis.step_response import first_order_response, golden_section_min
from protocol_runner.steps.calibration_check import analyse_step, step_fit


def _lfilter_response(command: np.ndarray, dt: float, tau: float, y0: float) -> np.ndarray:
    a = math.exp(-dt / tau)
    y, _ = lfilter([1.0 - a], [1.0, -a], command, zi=np.array([a * y0]))
    return np.concatenate(([y0], y[:-1]))


def test_the_response_is_lfilters_bit_for_bit() -> None:
    rng = np.random.default_rng(2)
    for _ in range(200):
        command = rng.standard_normal(int(rng.integers(1, 5000))) * 50.0
        dt, tau, y0 = float(rng.uniform(1e-4, 0.01)), float(rng.uniform(0.02, 2.0)), float(rng.normal(0, 30))
        assert np.array_equal(
            first_order_response(command, dt, tau, y0), _lfilter_response(command, dt, tau, y0)
        )


@pytest.mark.parametrize("centre", [0.021, 0.2, 0.73, 1.999])
def test_the_search_finds_a_minimum_to_its_width(centre: float) -> None:
    calls: list[float] = []

    def f(x: float) -> float:
        calls.append(x)
        return (x - centre) ** 2 + 0.1 * abs(x - centre) ** 3

    found = golden_section_min(f, 0.02, 2.0, 1e-5)
    assert abs(found - centre) <= 1e-5
    assert len(calls) <= 30  # 1.98 / 1e-5 shrinks in 26 golden steps
    with pytest.raises(ValueError):
        golden_section_min(f, 2.0, 0.02, 1e-5)


def _old_tau(time_s: np.ndarray, command: np.ndarray, angle: np.ndarray, window: float) -> float:
    """The former search: scipy's bounded Brent, tolerance 1e-4 s, on the same squared error."""
    _, sse = step_fit(time_s, command, angle, window)
    return float(minimize_scalar(sse, bounds=(0.02, 2.0), method="bounded", options={"xatol": 1e-4}).x)


def test_the_time_constant_is_within_1e4_s_of_the_former_search() -> None:
    rng = np.random.default_rng(5)
    for _ in range(12):
        tau_true = float(rng.uniform(0.05, 1.2))
        t = np.arange(6000) / 1000.0
        command = np.where(t >= 0.5, 65.0, 20.0)
        angle = _lfilter_response(command, 0.001, tau_true, 20.0) + rng.normal(0.0, 0.05, t.size)
        new = analyse_step(t, command, angle, 65.0, 1.0).time_constant_s
        assert abs(new - _old_tau(t, command, angle, 1.0)) <= 1e-4
        assert abs(new - tau_true) < 0.01
