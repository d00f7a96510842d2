"""Brace-off input scaling: Eq 8 and the iterative procedure replacing the lost Eq 9 (thesis §3.3.2)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pytest

from protocol_runner.analysis.scaling import range_scale, rig_runner, scale_brace_off_input
from protocol_runner.analysis.transition import transition_index
from protocol_runner.analysis.validation import AnalysisError

from .synth import first_order_lag, sine_command

RATE_HZ = 100.0


def _command() -> np.ndarray:
    _, cmd = sine_command(65.0, 65.0, 8.17, 40.0, RATE_HZ)
    return cmd


def lagged_plant(input_deg: np.ndarray) -> np.ndarray:
    """A bare robot: 0.2 s lag from park at 0 deg, gain 0.9 and +2 deg offset, smooth saturation."""
    lagged = first_order_lag(input_deg, 1.0 / RATE_HZ, 0.2, 0.0)
    distorted = 2.0 + 0.9 * lagged
    return 62.0 + 55.0 * np.tanh((distorted - 62.0) / 55.0)  # squeezes towards 7..117 deg


def _output_range(input_deg: np.ndarray, output_deg: np.ndarray) -> tuple[float, float]:
    start = transition_index(input_deg, output_deg)
    return float(output_deg[start:].min()), float(output_deg[start:].max())


def test_eq8_scale_is_the_ratio_of_output_ranges() -> None:
    on = np.array([25.0, 105.0, 60.0])
    off = np.array([0.0, 120.0, 50.0])
    assert range_scale(on, off) == pytest.approx(80.0 / 120.0)
    with pytest.raises(AnalysisError, match="range is zero"):
        range_scale(on, np.full(3, 4.0))


def test_iteration_converges_on_a_lagging_saturating_plant() -> None:
    target = (30.0, 95.0)
    result = scale_brace_off_input(_command(), target, lagged_plant, tolerance_deg=0.5, max_iterations=8)
    assert result.converged
    first, last = result.history[0], result.history[-1]
    assert first.range_error_deg > 10.0  # the unscaled brace-off run misses the target badly
    assert last.range_error_deg <= 0.5
    assert len(result.history) <= 5
    # errors shrink from one run to the next (the update is a contraction on this plant)
    errors = [it.range_error_deg for it in result.history]
    assert all(b < a for a, b in itertools.pairwise(errors))
    # the returned input really produces the target range when run again
    lo, hi = _output_range(result.input_deg, lagged_plant(result.input_deg))
    assert lo == pytest.approx(target[0], abs=0.5) and hi == pytest.approx(target[1], abs=0.5)
    # and the recorded Eq 8 scale is the ratio of the target range to that run's output range
    it = result.history[0]
    assert it.scale == pytest.approx(
        (target[1] - target[0]) / (it.output_range_deg[1] - it.output_range_deg[0])
    )


def test_an_affine_lag_plant_converges_in_few_runs() -> None:
    def plant(u: np.ndarray) -> np.ndarray:
        return 3.0 + 0.8 * first_order_lag(u, 1.0 / RATE_HZ, 0.2, u[0])

    result = scale_brace_off_input(_command(), (30.0, 95.0), plant, tolerance_deg=0.2)
    assert result.converged and len(result.history) <= 3


def test_unreachable_target_stops_at_the_iteration_limit_with_the_best_run() -> None:
    result = scale_brace_off_input(
        _command(), (20.0, 125.0), lagged_plant, max_iterations=4, input_limits_deg=(0.0, 140.0)
    )
    assert not result.converged
    assert len(result.history) == 4
    assert result.best.range_error_deg == min(it.range_error_deg for it in result.history)
    np.testing.assert_array_equal(result.output_deg, lagged_plant(result.input_deg))
    for it in result.history:  # the safety range of the input is respected
        assert it.input_range_deg[0] >= 0.0 and it.input_range_deg[1] <= 140.0


def test_bad_arguments_are_user_errors() -> None:
    with pytest.raises(AnalysisError, match="max > min"):
        scale_brace_off_input(_command(), (90.0, 30.0), lagged_plant)
    with pytest.raises(AnalysisError, match="does not move"):
        scale_brace_off_input(np.full(100, 3.0), (10.0, 20.0), lagged_plant)
    with pytest.raises(AnalysisError, match="same number of samples"):
        scale_brace_off_input(_command(), (30.0, 90.0), lambda u: u[:-1])


@dataclass(frozen=True)
class _FakeRecording:
    command_time_s: np.ndarray
    input_time_s: np.ndarray
    angle_deg: np.ndarray


def test_rig_runner_brings_the_1khz_angle_onto_the_command_ticks() -> None:
    def run_trajectory(cmd: np.ndarray) -> _FakeRecording:
        t_cmd = np.arange(cmd.shape[0]) / 100.0
        t_in = np.arange(cmd.shape[0] * 10) / 1000.0
        return _FakeRecording(t_cmd, t_in, 2.0 * t_in)  # angle = 2 deg/s * t

    run = rig_runner(run_trajectory)
    out = run(np.zeros(50))
    assert out.shape == (50,)
    np.testing.assert_allclose(out, 2.0 * np.arange(50) / 100.0)


def test_flat_brace_on_recording_is_an_analysis_error_not_a_crash() -> None:
    """A flat brace-on output (stuck joint) leaves nothing to scale: a clear AnalysisError, not a
    ZeroDivisionError from the collapsed input."""
    t = np.arange(0.0, 40.0, 1.0 / RATE_HZ)
    flat = 65.0 + 1e-12 * np.sin(2.0 * np.pi * t / 8.0)  # flat to float precision after filtering
    rng = np.random.default_rng(0)

    def noisy_offset_plant(input_deg: np.ndarray) -> np.ndarray:
        return input_deg + 2.0 + rng.normal(0.0, 0.01, input_deg.size)

    with pytest.raises(AnalysisError, match="does not move"):
        scale_brace_off_input(flat, (65.0, 65.0 + 1e-12), noisy_offset_plant, input_limits_deg=(0.0, 130.0))
