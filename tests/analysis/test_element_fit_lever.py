"""The element fit of the knee brace's lever spring (thesis §6.1, Eq 13-18) to a brace loop: what the
former spring fit did, now the lever_spring element's fit of max_preload_mm and zero_offset_deg."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.element_fit import branch_midline
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.errors import InvalidInput

from ..knee_device import fit_spring_model, spring_torque_nm

TRUE_PRELOAD_MM = 24.0
TRUE_OFFSET_DEG = 4.0


def _loop(friction_nm: float = 3.0, noise_nm: float = 0.0, k: float = 13.0, n: int = 3):
    t = np.arange(0.0, 30.0, 2e-3)
    angle = 62.0 + 40.0 * np.sin(2 * np.pi * t / 6.0)
    velocity = np.cos(2 * np.pi * t / 6.0)
    spring = spring_torque_nm(angle, k, n, max_preload_mm=TRUE_PRELOAD_MM, zero_offset_deg=TRUE_OFFSET_DEG)
    torque = spring + friction_nm * np.sign(velocity)
    if noise_nm:
        torque = torque + np.random.default_rng(5).normal(0.0, noise_nm, t.shape)
    return angle, torque, spring


def test_recovers_preload_and_zero_offset_through_friction_and_noise() -> None:
    angle, torque, _ = _loop(friction_nm=3.0, noise_nm=0.5)
    fit = fit_spring_model(angle, torque, 13.0, 3)
    assert fit.applicable
    assert fit.max_preload_mm == pytest.approx(TRUE_PRELOAD_MM, abs=0.5)
    assert fit.zero_offset_deg == pytest.approx(TRUE_OFFSET_DEG, abs=0.5)
    assert fit.rmse_nm < 0.2  # the midline cancels the friction and averages the noise
    # against every sample the friction (3 N m either way) and the noise remain
    assert fit.rmse_all_samples_nm == pytest.approx(np.hypot(3.0, 0.5), rel=0.05)
    np.testing.assert_allclose(
        fit.model_torque_nm,
        spring_torque_nm(
            fit.curve_angle_deg,
            13.0,
            3,
            max_preload_mm=fit.max_preload_mm,
            zero_offset_deg=fit.zero_offset_deg,
        ),
    )


def test_all_samples_target_also_fits_a_symmetric_loop() -> None:
    angle, torque, _ = _loop(friction_nm=1.0, k=4.4, n=1)
    fit = fit_spring_model(angle, torque, 4.4, 1, target="all_samples")
    assert fit.target == "all_samples"
    assert fit.max_preload_mm == pytest.approx(TRUE_PRELOAD_MM, abs=1.5)
    assert fit.zero_offset_deg == pytest.approx(TRUE_OFFSET_DEG, abs=1.0)


def test_midline_is_the_mean_of_the_branches() -> None:
    angle, torque, _spring = _loop(friction_nm=5.0)
    grid, mid = branch_midline(angle, torque, bin_width_deg=1.0)
    expected = spring_torque_nm(
        grid, 13.0, 3, max_preload_mm=TRUE_PRELOAD_MM, zero_offset_deg=TRUE_OFFSET_DEG
    )
    assert grid.min() > 22.0 - 1.0 and grid.max() < 102.0 + 1.0
    np.testing.assert_allclose(mid, expected, atol=0.3)


def test_no_spring_is_not_applicable_rather_than_a_crash() -> None:
    angle, torque, _ = _loop(friction_nm=3.0)
    fit = fit_spring_model(angle, torque, 0.0, 3)
    assert not fit.applicable
    assert "not applicable" in fit.reason
    assert np.isnan(fit.max_preload_mm) and np.isnan(fit.rmse_nm)


def test_bad_configuration_is_a_user_error() -> None:
    angle, torque, _ = _loop()
    with pytest.raises(InvalidInput, match="preload_index"):
        fit_spring_model(angle, torque, 13.0, 2.5)
    with pytest.raises(InvalidInput, match="stiffness_n_per_mm"):
        fit_spring_model(angle, torque, -1.0, 3)
    with pytest.raises(AnalysisError, match="unknown element-fit target"):
        fit_spring_model(angle, torque, 13.0, 3, target="median")  # type: ignore[arg-type]


def test_trimming_the_loop_ends_removes_the_rounded_corner_bias() -> None:
    # friction that reverses gradually over 6 deg after each turn (Dahl-like rounded corners)
    t = np.arange(0.0, 30.0, 2e-3)
    angle = 62.0 + 40.0 * np.sin(2 * np.pi * t / 6.0)
    spring = spring_torque_nm(angle, 13.0, 3, max_preload_mm=TRUE_PRELOAD_MM, zero_offset_deg=TRUE_OFFSET_DEG)
    friction = np.empty_like(angle)
    state, last = -3.0, angle[0]
    for i, a in enumerate(angle):  # first-order relaxation of the friction towards +-3 N m per degree moved
        step = a - last
        target = 3.0 if step >= 0 else -3.0
        state += (target - state) * min(1.0, abs(step) / 2.0)
        friction[i], last = state, a
    torque = spring + friction
    trimmed = fit_spring_model(angle, torque, 13.0, 3, trim_deg=8.0)
    untrimmed = fit_spring_model(angle, torque, 13.0, 3, trim_deg=0.0)
    assert abs(trimmed.zero_offset_deg - TRUE_OFFSET_DEG) < 0.3
    assert abs(trimmed.max_preload_mm - TRUE_PRELOAD_MM) < 0.5
    assert abs(untrimmed.zero_offset_deg - TRUE_OFFSET_DEG) > 1.0  # the corners tilt the untrimmed fit
    assert trimmed.rmse_nm < untrimmed.rmse_nm
    with pytest.raises(AnalysisError, match="trim"):
        branch_midline(angle, torque, trim_deg=-1.0)
