"""Facts about the safety envelope."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import EXIT_STOPPED_BY_CHECK, InvalidInput, StoppedByCheck
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.safety import (
    SafetyLimits,
    SafetyViolation,
    check_trajectory,
    clamp_volts,
    parking_ramp_deg,
)

RATE_HZ = 100.0
KNEE_EQ1_RANGE = (0.0, 130.0)
LIMITS = SafetyLimits(
    range_deg=(0.0, 130.0),
    max_rate_deg_s=120.0,
    max_accel_deg_s2=600.0,
    park_angle_deg=20.0,
    park_rate_deg_s=10.0,
)


def sinusoid(mean: float, amplitude: float, period_s: float, duration_s: float) -> np.ndarray:
    """Thesis Eq 24 sampled at the output rate."""
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    return mean + amplitude * np.sin(2 * np.pi * t / period_s)


def test_a_thesis_trajectory_passes() -> None:
    """R3 at full speed: 65 + 65 sin(2π t / 8.17), peak rate 50 deg/s (Appendix A)."""
    check_trajectory(sinusoid(65.0, 65.0, 2 * np.pi * 65 / 50, 65.0), RATE_HZ, LIMITS, where="trial-1")


def test_violation_is_a_stopped_by_check_with_exit_4() -> None:
    assert issubclass(SafetyViolation, StoppedByCheck)
    with pytest.raises(SafetyViolation) as info:
        check_trajectory(np.array([10.0, 131.0]), RATE_HZ, LIMITS, where="x")
    assert info.value.exit_code == EXIT_STOPPED_BY_CHECK


def test_range_violation_names_step_limit_worst_value_and_time() -> None:
    cmd = np.full(500, 60.0)
    cmd[200] = 131.0
    cmd[300] = 133.5  # the worst one
    cmd[400] = -1.0
    relaxed = SafetyLimits((0.0, 130.0), 1e6, 1e9, 20.0, 10.0)
    with pytest.raises(SafetyViolation) as info:
        check_trajectory(cmd, RATE_HZ, relaxed, where="set1/config4/trial2/brace_on")
    err = info.value
    assert (err.where, err.limit, err.value, err.index) == (
        "set1/config4/trial2/brace_on",
        "joint angle",
        133.5,
        300,
    )
    assert err.time_s == pytest.approx(3.0)
    message = str(err)
    assert "set1/config4/trial2/brace_on" in message and "133.5" in message and "t = 3.000 s" in message


def test_nan_is_a_violation() -> None:
    with pytest.raises(SafetyViolation, match="joint angle") as info:
        check_trajectory(np.array([10.0, np.nan, 10.0]), RATE_HZ, LIMITS, where="s")
    assert info.value.index == 1


def test_rate_violation_reports_the_fastest_sample() -> None:
    cmd = np.concatenate([np.full(10, 50.0), [51.0, 53.0, 53.0]])  # 100 then 200 deg/s
    relaxed_accel = SafetyLimits((0.0, 130.0), 120.0, 1e9, 20.0, 10.0)
    with pytest.raises(SafetyViolation) as info:
        check_trajectory(cmd, RATE_HZ, relaxed_accel, where="s")
    assert info.value.limit == "angular rate"
    assert info.value.value == pytest.approx(200.0)
    assert info.value.index == 11
    assert info.value.time_s == pytest.approx(0.11)


def test_rate_limit_boundary() -> None:
    relaxed_accel = SafetyLimits((0.0, 130.0), 120.0, 1e9, 20.0, 10.0)
    check_trajectory(np.arange(10.0, 100.0, 1.2), RATE_HZ, relaxed_accel, where="s")  # exactly 120 deg/s
    with pytest.raises(SafetyViolation, match="angular rate"):
        check_trajectory(np.arange(10.0, 100.0, 1.21), RATE_HZ, relaxed_accel, where="s")


def test_acceleration_violation() -> None:
    """A 50 deg/s sinusoid passes the rate limit; a 0.5 s period at small amplitude does not pass the
    acceleration limit (a = A (2π/p)² = 5 * 158 ≈ 790 deg/s² > 600)."""
    cmd = sinusoid(60.0, 5.0, 0.5, 2.0)
    assert np.max(np.abs(np.diff(cmd))) * RATE_HZ < LIMITS.max_rate_deg_s
    with pytest.raises(SafetyViolation) as info:
        check_trajectory(cmd, RATE_HZ, LIMITS, where="s")
    assert info.value.limit == "angular acceleration"
    assert abs(info.value.value) > 600.0


def test_step_from_initial_angle_is_checked_only_when_asked() -> None:
    cmd = np.full(100, 45.0)
    check_trajectory(cmd, RATE_HZ, LIMITS, where="calibration")
    with pytest.raises(SafetyViolation, match="angular rate") as info:
        check_trajectory(cmd, RATE_HZ, LIMITS, where="calibration", initial_deg=20.0)
    assert info.value.index == 0


def test_volts_after_the_command_table_are_checked() -> None:
    """A table that asks for a commanded angle beyond the Eq 1 range would saturate the output."""
    table = CalibrationTable(np.array([0.0, 130.0]), np.array([-3.0, 127.0]), "real_deg", "input_deg")
    cmd = np.full(50, 1.0)
    check_trajectory(cmd, RATE_HZ, LIMITS, where="s")  # fine without the table
    with pytest.raises(SafetyViolation, match="voltage") as info:
        check_trajectory(cmd, RATE_HZ, LIMITS, where="s", command_table=table, volts_range_deg=KNEE_EQ1_RANGE)
    assert info.value.units == "V"
    assert info.value.value == pytest.approx(-10.0 - 2.0 / 130.0 * 20.0)


def test_bad_arguments_are_invalid_input() -> None:
    with pytest.raises(InvalidInput, match="non-empty"):
        check_trajectory(np.array([]), RATE_HZ, LIMITS, where="s")
    with pytest.raises(InvalidInput, match="rate"):
        check_trajectory(np.array([1.0]), 0.0, LIMITS, where="s")
    with pytest.raises(InvalidInput, match="park_angle_deg"):
        SafetyLimits((0.0, 130.0), 100.0, 500.0, 140.0, 10.0)
    with pytest.raises(InvalidInput, match="park_rate_deg_s"):
        SafetyLimits((0.0, 130.0), 10.0, 500.0, 20.0, 20.0)


def test_clamp_volts() -> None:
    np.testing.assert_array_equal(
        clamp_volts([-12.0, -10.0, 0.5, 10.0, 10.5]), [-10.0, -10.0, 0.5, 10.0, 10.0]
    )


def test_parking_ramp_ends_at_park_angle_and_respects_limits() -> None:
    ramp = parking_ramp_deg(110.0, LIMITS, RATE_HZ)
    assert ramp[0] == 110.0
    assert ramp[-1] == LIMITS.park_angle_deg
    assert np.all(np.diff(ramp) <= 0)
    assert np.max(np.abs(np.diff(ramp))) * RATE_HZ == pytest.approx(LIMITS.park_rate_deg_s, rel=1e-6)
    check_trajectory(ramp, RATE_HZ, LIMITS, where="park")
    # About 90° at 10 deg/s: 9 s plus the acceleration phases.
    assert 9.0 < (ramp.size - 1) / RATE_HZ < 9.5


def test_parking_ramp_at_the_park_angle_is_one_sample() -> None:
    np.testing.assert_array_equal(parking_ramp_deg(20.0, LIMITS, RATE_HZ), [20.0])


@settings(max_examples=60)
@given(
    from_deg=st.floats(min_value=-20.0, max_value=150.0),
    rate_hz=st.sampled_from([50.0, 100.0, 1000.0]),
    park_rate=st.floats(min_value=0.5, max_value=120.0),
    accel=st.floats(min_value=1.0, max_value=5000.0),
)
def test_parking_ramp_property(from_deg: float, rate_hz: float, park_rate: float, accel: float) -> None:
    limits = SafetyLimits((0.0, 130.0), 120.0, accel, 45.0, park_rate)
    ramp = parking_ramp_deg(from_deg, limits, rate_hz)
    assert ramp[0] == pytest.approx(from_deg) and ramp[-1] == 45.0
    assert np.all(np.diff(ramp) * np.sign(45.0 - from_deg) >= -1e-12)  # monotone towards the park angle
    wide = SafetyLimits((min(from_deg, 0.0), max(from_deg, 130.0)), 120.0, accel, 45.0, park_rate)
    check_trajectory(ramp, rate_hz, wide, where="park")
