"""Facts about the Eq 1-3 conversions and the board code formats (thesis §2.4.1, DAQ USB facts)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.conversions import (
    ai12_code_to_volts,
    ai16_code_to_volts,
    angle_to_volts,
    ao16_code_to_volts,
    torque_to_volts,
    volts_to_ai16_code,
    volts_to_angle,
    volts_to_ao16_code,
    volts_to_torque,
)
from tests.rsst_reference import RSST_JOINTS, volts_to_ai12_code

KNEE = RSST_JOINTS[9]
AO_LSB = 1.0 / 3276.8
AI12_LSB = 20.0 / 4096.0
AI16_LSB = 10.0 / 32768.0

joint_numbers = st.sampled_from(sorted(RSST_JOINTS))
unit = st.floats(min_value=0.0, max_value=1.0)


def test_all_twelve_joints_from_tables_1_to_3() -> None:
    assert sorted(RSST_JOINTS) == list(range(1, 13))
    assert KNEE.name == "Knee Flexion"
    assert KNEE.range_deg == (0.0, 130.0)
    assert KNEE.torque_range_nm == (-84.8, 84.8)
    assert RSST_JOINTS[1].range_deg == (-15.0, 180.0)
    assert RSST_JOINTS[7].torque_range_nm == (-45.2, 226.0)
    assert RSST_JOINTS[11].range_deg == (-45.0, 30.0)
    for joint in RSST_JOINTS.values():
        assert joint.range_deg[0] < joint.range_deg[1]
        assert joint.torque_range_nm[0] < joint.torque_range_nm[1]


@pytest.mark.parametrize(("angle", "volts"), [(0.0, -10.0), (130.0, 10.0), (65.0, 0.0), (32.5, -5.0)])
def test_knee_eq1_hand_values(angle: float, volts: float) -> None:
    assert angle_to_volts(angle, KNEE.range_deg) == pytest.approx(volts, abs=1e-12)
    assert volts_to_angle(volts, KNEE.range_deg) == pytest.approx(angle, abs=1e-12)


def test_shoulder_flexion_eq1_hand_values() -> None:
    shoulder = RSST_JOINTS[1]  # -15..180 deg: 195 deg over 20 V
    assert angle_to_volts(-15.0, shoulder.range_deg) == pytest.approx(-10.0)
    assert angle_to_volts(82.5, shoulder.range_deg) == pytest.approx(0.0)
    assert angle_to_volts(0.0, shoulder.range_deg) == pytest.approx(-10.0 + 15.0 / 195.0 * 20.0)


def test_knee_eq3_hand_values() -> None:
    assert volts_to_torque(10.0, KNEE.torque_range_nm) == pytest.approx(84.8)
    assert volts_to_torque(0.0, KNEE.torque_range_nm) == pytest.approx(0.0, abs=1e-12)
    assert volts_to_torque(-5.0, KNEE.torque_range_nm) == pytest.approx(-42.4)
    hip_abduction = RSST_JOINTS[7]  # asymmetric: -45.2..226 N·m
    assert volts_to_torque(0.0, hip_abduction.torque_range_nm) == pytest.approx((226.0 - 45.2) / 2)


def test_conversions_are_vectorised() -> None:
    angles = np.array([[0.0, 65.0], [130.0, 97.5]])
    volts = angle_to_volts(angles, KNEE.range_deg)
    assert volts.shape == (2, 2)
    np.testing.assert_allclose(volts, [[-10.0, 0.0], [10.0, 5.0]])


def test_bad_range_is_invalid_input() -> None:
    with pytest.raises(InvalidInput, match="range_deg"):
        angle_to_volts(10.0, (130.0, 0.0))


@settings(max_examples=80)
@given(number=joint_numbers, u=unit)
def test_angle_volts_round_trip(number: int, u: float) -> None:
    joint = RSST_JOINTS[number]
    lo, hi = joint.range_deg
    angle = lo + u * (hi - lo)
    volts = angle_to_volts(angle, joint.range_deg)
    assert -10.0 - 1e-9 <= volts <= 10.0 + 1e-9
    assert volts_to_angle(volts, joint.range_deg) == pytest.approx(angle, abs=1e-9)


@settings(max_examples=80)
@given(number=joint_numbers, u=unit)
def test_torque_volts_round_trip(number: int, u: float) -> None:
    joint = RSST_JOINTS[number]
    lo, hi = joint.torque_range_nm
    torque = lo + u * (hi - lo)
    assert volts_to_torque(torque_to_volts(torque, joint.torque_range_nm), joint.torque_range_nm) == (
        pytest.approx(torque, abs=1e-9)
    )


def test_ao16_codes_of_the_usb3105() -> None:
    assert int(volts_to_ao16_code(0.0)) == 32768
    assert int(volts_to_ao16_code(-10.0)) == 0
    assert int(volts_to_ao16_code(10.0)) == 65535  # 65536 clamps: full scale is +9.99969 V
    assert int(volts_to_ao16_code(5.0)) == 32768 + 16384
    assert volts_to_ao16_code(np.array([1.0])).dtype == np.uint16


@settings(max_examples=100)
@given(volts=st.floats(min_value=-10.0, max_value=10.0 - AO_LSB))
def test_ao16_round_trip_within_half_lsb(volts: float) -> None:
    back = float(ao16_code_to_volts(volts_to_ao16_code(volts)))
    assert abs(back - volts) <= AO_LSB / 2 + 1e-12


@settings(max_examples=50)
@given(volts=st.floats(min_value=10.0, max_value=1e6) | st.floats(min_value=-1e6, max_value=-10.0))
def test_ao16_clamps_at_the_rails(volts: float) -> None:
    assert int(volts_to_ao16_code(volts)) == (65535 if volts > 0 else 0)


def test_ai12_codes_of_the_dt9814() -> None:
    assert int(volts_to_ai12_code(0.0)) == 0
    assert int(volts_to_ai12_code(-10.0)) == -2048
    assert int(volts_to_ai12_code(10.0)) == 2047
    assert float(ai12_code_to_volts(1024)) == pytest.approx(5.0)
    assert float(ai12_code_to_volts(-2048)) == pytest.approx(-10.0)
    assert volts_to_ai12_code(np.array([1.0])).dtype == np.int32


@settings(max_examples=100)
@given(volts=st.floats(min_value=-10.0, max_value=10.0 - AI12_LSB))
def test_ai12_round_trip_within_half_lsb(volts: float) -> None:
    back = float(ai12_code_to_volts(volts_to_ai12_code(volts)))
    assert abs(back - volts) <= AI12_LSB / 2 + 1e-12


@settings(max_examples=50)
@given(volts=st.floats(min_value=10.0, max_value=1e6) | st.floats(min_value=-1e6, max_value=-10.0))
def test_ai12_clamps_at_the_rails(volts: float) -> None:
    assert int(volts_to_ai12_code(volts)) == (2047 if volts > 0 else -2048)


def test_ai16_codes_of_the_usb1608fs_plus() -> None:
    assert int(volts_to_ai16_code(0.0)) == 32768
    assert int(volts_to_ai16_code(-10.0)) == 0
    assert int(volts_to_ai16_code(10.0)) == 65535
    assert float(ai16_code_to_volts(49152)) == pytest.approx(5.0)


@settings(max_examples=100)
@given(volts=st.floats(min_value=-10.0, max_value=10.0 - AI16_LSB))
def test_ai16_round_trip_within_half_lsb(volts: float) -> None:
    back = float(ai16_code_to_volts(volts_to_ai16_code(volts)))
    assert abs(back - volts) <= AI16_LSB / 2 + 1e-12


def test_nan_volts_are_never_turned_into_codes() -> None:
    for convert in (volts_to_ao16_code, volts_to_ai12_code, volts_to_ai16_code):
        with pytest.raises(InvalidInput, match="NaN"):
            convert(np.array([0.0, np.nan]))
