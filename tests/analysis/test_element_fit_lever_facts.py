"""The spring fit's target: the midline on the range both branches cover, and the all-samples fit weighting
every sample once (thesis §6.1)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from protocol_runner.analysis.element_fit import branch_midline
from protocol_runner.analysis.validation import AnalysisError

from ..knee_device import fit_spring_model, spring_torque_nm


def _uneven_loop() -> tuple[np.ndarray, np.ndarray]:
    """Loading sweeps 10 -> 100 deg, unloading only 100 -> 20 deg; torque a line plus 2 N m of friction:
    the branches share only 20..100 deg."""
    up = np.linspace(10.0, 100.0, 901)
    down = np.linspace(100.0, 20.0, 801)[1:]
    angle = np.concatenate([up, down])
    labels = np.concatenate([np.ones(901), -np.ones(800)])
    return angle, 0.3 * angle - 5.0 + 2.0 * labels


def test_midline_spans_only_the_angles_both_branches_cover_minus_the_trim() -> None:
    angle, torque = _uneven_loop()
    grid, _ = branch_midline(angle, torque, bin_width_deg=1.0, trim_deg=0.0)
    assert 20.0 <= grid[0] < 21.0 and 99.0 < grid[-1] <= 100.0
    grid5, mid5 = branch_midline(angle, torque, bin_width_deg=1.0, trim_deg=5.0)
    assert grid5[0] == pytest.approx(grid[0] + 5.0) and grid5[-1] <= grid[-1] - 5.0 + 1e-9
    assert grid5[-1] > grid[-1] - 6.0
    np.testing.assert_allclose(np.diff(grid5), 1.0)
    # in the middle of the common range the friction cancels: the midline is the line itself
    inner = (grid5 > 30.0) & (grid5 < 80.0)
    np.testing.assert_allclose(mid5[inner], 0.3 * grid5[inner] - 5.0, atol=1e-9)


def test_all_samples_fit_is_the_least_squares_fit_over_every_sample() -> None:
    """Binning into 0.05 deg cells weighted by the square root of their counts must give the optimum of the
    plain sum over samples; a joint that dwells (many samples at few angles) makes unweighted bins differ."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 12.0, 2e-3)
    angle = 60.0 + 40.0 * np.sin(2 * np.pi * t / 6.0) ** 3  # slow near 60 deg: many samples there
    angle = np.round(angle / 0.05) * 0.05 + 0.01  # one angle per fine bin, so binning loses nothing
    spring = spring_torque_nm(angle, 13.0, 3, max_preload_mm=24.0, zero_offset_deg=4.0)
    torque = spring + 4.0 * np.sin(np.radians(3 * angle)) + rng.normal(0.0, 0.5, angle.shape)
    fit = fit_spring_model(angle, torque, 13.0, 3, target="all_samples")

    def residual(p: np.ndarray) -> np.ndarray:
        return spring_torque_nm(angle, 13.0, 3, max_preload_mm=p[0], zero_offset_deg=p[1]) - torque

    direct = least_squares(
        residual, np.array([fit.max_preload_mm, fit.zero_offset_deg]), x_scale=(10.0, 10.0)
    )
    assert fit.max_preload_mm == pytest.approx(direct.x[0], abs=0.02)
    assert fit.zero_offset_deg == pytest.approx(direct.x[1], abs=0.02)
    assert fit.rmse_nm == fit.rmse_all_samples_nm == pytest.approx(np.sqrt(np.mean(direct.fun**2)), rel=1e-3)


def test_the_midline_reaches_the_top_of_a_loop_that_dwells_there() -> None:
    # a dwell at 100 deg: both branches' last 1-deg bins hold 100 deg, so the common range ends at 100 deg
    # and a 0.2 deg trim keeps the grid point 99.65 deg (grid from the unloading start bin, 20.45 deg)
    up = np.linspace(10.0, 100.0, 901)
    dwell = np.full(20, 100.0)
    down = np.linspace(100.0, 20.0, 801)[1:]
    angle = np.concatenate([up, dwell, down])
    torque = 0.3 * angle
    grid, _ = branch_midline(angle, torque, bin_width_deg=1.0, trim_deg=0.2)
    assert grid[0] == pytest.approx(20.45 + 0.2)
    assert grid[-1] == pytest.approx(99.65)


def test_no_spring_reports_stiffness_zero() -> None:
    angle = np.linspace(10.0, 100.0, 50)
    fit = fit_spring_model(np.concatenate([angle, angle[::-1]]), np.zeros(100), 0.0, 2)
    assert not fit.applicable and "stiffness 0" in fit.reason
    assert (
        fit.elements[0].number("stiffness_n_per_mm") == 0.0 and fit.elements[0].number("preload_index") == 2
    )


def test_three_angles_are_enough_for_the_two_parameters_and_two_are_not() -> None:
    angle = np.array([40.01, 60.01, 80.01])  # three fine (0.05 deg) bins
    torque = spring_torque_nm(angle, 13.0, 3, max_preload_mm=24.0, zero_offset_deg=4.0)
    fit = fit_spring_model(angle, torque, 13.0, 3, target="all_samples")
    assert fit.max_preload_mm == pytest.approx(24.0, abs=1e-3)
    assert fit.zero_offset_deg == pytest.approx(4.0, abs=1e-3)
    with pytest.raises(AnalysisError, match="only 2 points"):
        fit_spring_model(angle[:2], torque[:2], 13.0, 3, target="all_samples")


def test_the_reason_names_what_was_fitted() -> None:
    t = np.arange(0.0, 12.0, 2e-3)
    angle = 62.0 + 40.0 * np.sin(2 * np.pi * t / 6.0)
    torque = spring_torque_nm(angle, 13.0, 3, max_preload_mm=24.0, zero_offset_deg=4.0)
    assert fit_spring_model(angle, torque, 13.0, 3).reason == "least squares on the loop midline"
    assert (
        fit_spring_model(angle, torque, 13.0, 3, target="all_samples").reason
        == "least squares on the samples"
    )


def test_a_true_value_beyond_a_bound_is_fitted_at_the_bound() -> None:
    t = np.arange(0.0, 12.0, 5e-3)
    angle = 65.0 + 45.0 * np.sin(2 * np.pi * t / 6.0)
    torque = spring_torque_nm(angle, 13.0, 3, max_preload_mm=24.0, zero_offset_deg=45.0)
    fit = fit_spring_model(angle, torque, 13.0, 3)  # zero offset bounded to +-40 deg
    assert fit.zero_offset_deg == pytest.approx(40.0)
    low = spring_torque_nm(angle, 13.0, 3, max_preload_mm=24.0, zero_offset_deg=-45.0)
    assert fit_spring_model(angle, low, 13.0, 3).zero_offset_deg == pytest.approx(-40.0)
