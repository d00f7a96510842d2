"""Facts of the brace-off scaling procedure (§3.3.2) that the report's numbers rest on."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.scaling import range_scale, scale_brace_off_input, scale_brace_off_inputs
from protocol_runner.analysis.validation import AnalysisError

from .synth import sine_command


def _command() -> np.ndarray:
    return sine_command(65.0, 65.0, 8.17, 20.0, 100.0)[1]


class _ErraticPlant:
    """A plant whose gain about the input's mid-range changes from run to run (a brace-off robot whose
    behaviour drifts): the second run is the closest to the target, the later ones are worse."""

    def __init__(self, gains: list[float]) -> None:
        self.gains = gains
        self.inputs: list[np.ndarray] = []
        self.outputs: list[np.ndarray] = []

    def __call__(self, u: np.ndarray) -> np.ndarray:
        gain = self.gains[len(self.inputs)]
        mid = 0.5 * (u.max() + u.min())
        out = mid + gain * (u - mid)
        self.inputs.append(u.copy())
        self.outputs.append(out)
        return out


def test_the_best_run_is_returned_not_the_last() -> None:
    plant = _ErraticPlant([1.0, 1.05, 3.0, 0.3])
    target = (30.0, 95.0)
    result = scale_brace_off_input(_command(), target, plant, tolerance_deg=1e-9, max_iterations=4)
    errors = [it.range_error_deg for it in result.history]
    assert not result.converged and len(errors) == 4
    best = int(np.argmin(errors))
    assert best == 1 and errors[-1] > 10 * errors[best]  # the last run is clearly not the best
    assert result.best.iteration == best
    np.testing.assert_array_equal(result.input_deg, plant.inputs[best])
    np.testing.assert_array_equal(result.output_deg, plant.outputs[best])


def test_first_correction_matches_amplitude_and_mid_range_of_an_affine_plant() -> None:
    """Output = 0.5 x input + 10 deg (no lag): the Eq 8 amplitude step and the Newton mid-range step make
    the second run hit the target range exactly, and every run records what it ran and measured."""

    def plant(u: np.ndarray) -> np.ndarray:
        return 10.0 + 0.5 * u

    u = _command()
    target = (40.0, 80.0)
    result = scale_brace_off_input(u, target, plant, tolerance_deg=1e-6, transition_tolerance_deg=200.0)
    assert result.converged and len(result.history) == 2
    first, second = result.history
    assert first.input_range_deg == pytest.approx((u.min(), u.max()))
    assert first.output_range_deg == pytest.approx((10.0 + 0.5 * u.min(), 10.0 + 0.5 * u.max()))
    assert first.scale == pytest.approx(40.0 / (0.5 * (u.max() - u.min())))
    assert first.range_error_deg == pytest.approx(
        max(abs(10 + 0.5 * u.min() - 40), abs(10 + 0.5 * u.max() - 80))
    )
    assert second.output_range_deg == pytest.approx(target, abs=1e-9)
    assert second.range_error_deg == pytest.approx(0.0, abs=1e-9)
    # the input that hits 40..80 deg through out = 10 + 0.5 in is 60..140 deg
    assert second.input_range_deg == pytest.approx((60.0, 140.0))
    assert (result.input_deg.min(), result.input_deg.max()) == pytest.approx((60.0, 140.0))


def test_a_run_inside_the_tolerance_ends_the_iteration() -> None:
    """A run whose range error equals the tolerance counts as converged (error <= tolerance)."""

    def plant(u: np.ndarray) -> np.ndarray:
        return u + 1.0  # every range end 1 deg high

    u = _command()
    target = (float(u.min()), float(u.max()))
    result = scale_brace_off_input(u, target, plant, tolerance_deg=1.0, max_iterations=3)
    assert result.converged and len(result.history) == 1
    assert result.history[0].range_error_deg == pytest.approx(1.0)


def test_eq8_scale_uses_both_ends_of_both_ranges() -> None:
    on = np.array([10.0, 50.0, 30.0])  # range 40
    off = np.array([-20.0, 60.0, 0.0])  # range 80
    assert range_scale(on, off) == pytest.approx(0.5)
    assert range_scale(off, on) == pytest.approx(2.0)


def test_the_default_transition_is_the_thesis_three_points_within_five_degrees() -> None:
    u = _command()

    def plant(v: np.ndarray) -> np.ndarray:
        out = v.copy()
        out[:10] += 20.0  # start-up: 20 deg off ...
        out[3:5] = v[3:5]  # ... except two samples on the command: not yet three in a row
        return out

    result = scale_brace_off_input(u, (float(u.min()), float(u.max())), plant, max_iterations=1)
    assert result.history[0].transition_index == 10
    assert result.converged and result.history[0].range_error_deg == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"target_range_deg": (50.0, 50.0)}, "max > min"),
        ({"tolerance_deg": 0.0}, "tolerance must be positive"),
        ({"max_iterations": 0}, "at least one iteration"),
        ({"input_limits_deg": (80.0, 80.0)}, "input limits must be"),  # an empty range to move in
        ({"input_limits_deg": (90.0, 80.0)}, "input limits must be"),  # or a reversed one
    ],
)
def test_a_target_or_setting_that_leaves_nothing_to_do_is_a_user_error(kwargs: dict, message: str) -> None:
    args = {"target_range_deg": (30.0, 95.0), **kwargs}
    with pytest.raises(AnalysisError, match=message):
        scale_brace_off_input(_command(), run=lambda v: v, **args)


def test_a_single_iteration_is_allowed_and_the_default_tolerance_is_a_tenth_of_a_degree() -> None:
    u = _command()
    target = (float(u.min()), float(u.max()))
    one = scale_brace_off_input(u, target, lambda v: v + 0.15, max_iterations=1)
    assert len(one.history) == 1 and not one.converged  # 0.15 deg off: outside the default 0.1 deg
    assert scale_brace_off_input(u, target, lambda v: v + 0.09, max_iterations=1).converged


def test_an_output_that_does_not_move_after_the_transition_is_a_user_error() -> None:
    with pytest.raises(AnalysisError):
        scale_brace_off_input(_command(), (30.0, 95.0), lambda v: np.full_like(v, v[0]))


def test_by_default_the_output_range_starts_at_the_thesis_transition_point() -> None:
    """Thesis §3.3.1: the transition ends once the output is within 5 deg of the command for 3 points.
    A run whose first ten samples lag 5.5 deg below the command has its range measured after them."""
    k = np.arange(600)
    command = 65.0 - 45.0 * np.cos(2.0 * np.pi * k / 200.0)  # 20..110 deg, starting at 20

    def run(x: np.ndarray) -> np.ndarray:
        return x - np.where(np.arange(x.size) < 10, 5.5, 0.0)

    result = scale_brace_off_input(command, (20.0, 110.0), run)
    first = result.history[0]
    assert first.transition_index == 10
    assert first.output_range_deg == pytest.approx((20.0, 110.0), abs=0.05)
    assert result.converged and len(result.history) == 1


@pytest.mark.parametrize("level_deg", [100.0, -100.0])
def test_an_input_moving_by_less_than_a_billionth_of_its_level_is_flat(level_deg: float) -> None:
    """The flatness test is relative to the level (1e-9 of 1 + |mid-range|): at +-100 deg a wiggle of
    5e-8 deg is flat, one of 1e-6 deg is not (it is scaled up like any other trajectory)."""
    wave = np.sin(np.linspace(0.0, 6.0 * np.pi, 300))
    with pytest.raises(AnalysisError, match="does not move"):
        scale_brace_off_input(level_deg + 2.5e-8 * wave, (20.0, 110.0), lambda x: x, max_iterations=1)
    moving = scale_brace_off_input(level_deg + 5e-7 * wave, (20.0, 110.0), lambda x: x, max_iterations=1)
    assert moving.history[0].output_range_deg[1] > moving.history[0].output_range_deg[0]


def test_joints_run_together_are_scaled_each_by_its_own_factor_and_a_matched_joint_keeps_its_input() -> None:
    """Two joints in one robot run per iteration: the first already follows its target (output = input),
    the second has a gain of 0.5 and an offset of 10 deg. The first keeps its input while the second is
    corrected (Eq 8 amplitude, mid-range step), both end within the tolerance, and one run is kept for both."""
    u = _command()
    runs: list[list[np.ndarray]] = []

    def robot(inputs: list[np.ndarray]) -> list[np.ndarray]:
        runs.append([x.copy() for x in inputs])
        return [inputs[0].copy(), 10.0 + 0.5 * inputs[1]]

    lo, hi = float(u.min()), float(u.max())
    results = scale_brace_off_inputs(
        [u, u], [(lo, hi), (40.0, 80.0)], robot, tolerance_deg=1e-6, transition_tolerance_deg=200.0
    )
    first, second = results
    assert len(runs) == 2
    np.testing.assert_array_equal(runs[0][0], runs[1][0])  # the matched joint kept its input
    assert not np.array_equal(runs[0][1], runs[1][1])  # the other was scaled
    assert first.history[0].range_error_deg <= 1e-6 and second.history[0].range_error_deg > 1.0
    assert first.converged and second.converged and first.kept == second.kept == 1
    assert second.best.output_range_deg == pytest.approx((40.0, 80.0), abs=1e-6)
    np.testing.assert_array_equal(second.input_deg, runs[1][1])
