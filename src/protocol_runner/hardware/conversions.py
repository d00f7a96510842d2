"""Linear conversions between joint quantities, volts and board codes (thesis §2.4.1, Eq 1-3, Tables 1-3).

- Eq 1: commanded joint angle -> output volts, linear over the joint's angle range (Table 2) onto ±10 V.
- Eq 2: angle telemetry volts -> joint angle (the inverse map of Eq 1).
- Eq 3: torque telemetry volts -> joint torque, linear over the joint's torque range (Table 3).
- Board codes (reference/daq-usb-protocols.md):
  USB-3105 analog output, 16-bit ±10 V: ideal code k = 32768 + 3276.8 V, rounded, clamped to 0..65535.
  DT9814 analog input, 12-bit ±10 V two's complement: V = 20 * code / 4096, code in -2048..2047.
  USB-1608FS-Plus analog input, 16-bit ±10 V offset binary: V = (k - 32768) * 10 / 32768.

All functions are vectorised (arrays in, arrays out) and never clamp angles or torques: range safety is the
job of `hardware/safety.py`. Only the code conversions clamp, because a board cannot represent more.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

FloatArray = npt.NDArray[np.float64]
ArrayLike = npt.ArrayLike

VOLTS_RANGE: tuple[float, float] = (-10.0, 10.0)
"""Analog range of the RSST's VME command inputs and telemetry outputs (thesis §2.2)."""

AO16_ZERO_CODE = 32768
AO16_CODES_PER_VOLT = 3276.8  # USB-3105 ±10 V: LSB = 305.2 µV
AO16_MAX_CODE = 65535
AI12_MIN_CODE = -2048
AI12_MAX_CODE = 2047
AI12_VOLTS_PER_CODE = 20.0 / 4096.0  # DT9814 ±10 V: LSB = 4.883 mV
AI16_ZERO_CODE = 32768
AI16_VOLTS_PER_CODE = 10.0 / 32768.0  # USB-1608FS-Plus ±10 V: LSB = 305.2 µV
AI16_MAX_CODE = 65535


def _check_range(pair: tuple[float, float], what: str) -> tuple[float, float]:
    lo, hi = float(pair[0]), float(pair[1])
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise InvalidInput(
            f"{what} must be two finite numbers (minimum, maximum) with maximum > minimum, got {pair!r}"
        )
    return lo, hi


def _conversion(joint_name: str, to_volts: bool) -> Callable[[ArrayLike, tuple[float, float]], FloatArray]:
    """Eq 1-3: the straight line through the ends of the joint's range (the argument `joint_name`, named in
    the error) and of the volts range, to volts or from volts. Not clamped."""

    def convert(values: ArrayLike, joint_range: tuple[float, float]) -> FloatArray:
        (s0, s1), (d0, d1) = _check_range(joint_range, joint_name), VOLTS_RANGE
        if not to_volts:
            (s0, s1), (d0, d1) = (d0, d1), (s0, s1)
        result: FloatArray = d0 + (np.asarray(values, dtype=np.float64) - s0) * ((d1 - d0) / (s1 - s0))
        return result

    return convert


angle_to_volts = _conversion("range_deg", to_volts=True)  # Eq 1: the commanded angle's output volts
volts_to_angle = _conversion("range_deg", to_volts=False)  # Eq 2: angle telemetry volts -> joint angle
volts_to_torque = _conversion("torque_range_nm", to_volts=False)  # Eq 3: torque telemetry volts -> torque
torque_to_volts = _conversion("torque_range_nm", to_volts=True)  # Eq 3 inverted: what the robot outputs


def volts_to_ao16_code(volts: ArrayLike) -> npt.NDArray[np.uint16]:
    """USB-3105 ±10 V ideal code: k = round(32768 + 3276.8 V), clamped to 0..65535 (so +10 V -> 65535,
    i.e. +9.99969 V). NaN is rejected rather than sent."""
    v = np.asarray(volts, dtype=np.float64)
    if np.isnan(v).any():
        raise InvalidInput("cannot convert NaN volts to an analog output code")
    k = np.rint(AO16_ZERO_CODE + AO16_CODES_PER_VOLT * v)
    result: npt.NDArray[np.uint16] = np.clip(k, 0, AO16_MAX_CODE).astype(np.uint16)
    return result


def ao16_code_to_volts(code: ArrayLike) -> FloatArray:
    """Volts of a USB-3105 ±10 V code: V = (k - 32768) / 3276.8."""
    k = np.asarray(code, dtype=np.float64)
    result: FloatArray = (k - AO16_ZERO_CODE) / AO16_CODES_PER_VOLT
    return result


def ai12_code_to_volts(code: ArrayLike) -> FloatArray:
    """DT9814 12-bit ±10 V: V = 20 * code / 4096."""
    result: FloatArray = np.asarray(code, dtype=np.float64) * AI12_VOLTS_PER_CODE
    return result


def volts_to_ai16_code(volts: ArrayLike) -> npt.NDArray[np.int32]:
    """USB-1608FS-Plus 16-bit ±10 V offset-binary code: round(32768 + V * 32768 / 10), clamped 0..65535."""
    v = np.asarray(volts, dtype=np.float64)
    if np.isnan(v).any():
        raise InvalidInput("cannot convert NaN volts to an analog input code")
    k = np.rint(AI16_ZERO_CODE + v / AI16_VOLTS_PER_CODE)
    result: npt.NDArray[np.int32] = np.clip(k, 0, AI16_MAX_CODE).astype(np.int32)
    return result


def ai16_code_to_volts(code: ArrayLike) -> FloatArray:
    """USB-1608FS-Plus 16-bit ±10 V: V = (k - 32768) * 10 / 32768."""
    result: FloatArray = (np.asarray(code, dtype=np.float64) - AI16_ZERO_CODE) * AI16_VOLTS_PER_CODE
    return result
