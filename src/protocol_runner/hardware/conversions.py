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

from typing import Protocol

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


def _linear_map(
    values: ArrayLike, src: tuple[str, tuple[float, float]], dst: tuple[str, tuple[float, float]]
) -> FloatArray:
    """The straight line through (src_min, dst_min) and (src_max, dst_max) that Eq 1-3 all are; `src` and
    `dst` are (argument name, (minimum, maximum)), each range checked and named in the error."""
    x = np.asarray(values, dtype=np.float64)
    s0, s1 = _check_range(src[1], src[0])
    d0, d1 = _check_range(dst[1], dst[0])
    result: FloatArray = d0 + (x - s0) * ((d1 - d0) / (s1 - s0))
    return result


class LinearConversion(Protocol):
    """One of Eq 1-3: `values`, the joint's range (degrees or newton-metres), the volts range (±10 V)."""

    def __call__(
        self, values: ArrayLike, joint_range: tuple[float, float], volts_range: tuple[float, float] = ...
    ) -> FloatArray: ...


def _equation(src: str, dst: str) -> LinearConversion:
    """The conversion from the range named `src` to the range named `dst`, one of them "volts_range" (the
    volts side), the other the joint's range (its name is what an error about it says). Not clamped."""
    joint_name = src if dst == "volts_range" else dst

    def convert(
        values: ArrayLike, joint_range: tuple[float, float], volts_range: tuple[float, float] = VOLTS_RANGE
    ) -> FloatArray:
        ranges = {joint_name: joint_range, "volts_range": volts_range}
        return _linear_map(values, (src, ranges[src]), (dst, ranges[dst]))

    convert.__doc__ = (
        f"{src} -> {dst} (thesis Eq 1-3, the straight line through the range ends). Not clamped."
    )
    return convert


angle_to_volts = _equation("range_deg", "volts_range")  # Eq 1: the commanded angle's output volts
volts_to_angle = _equation("volts_range", "range_deg")  # Eq 2: angle telemetry volts -> joint angle
volts_to_torque = _equation("volts_range", "torque_range_nm")  # Eq 3: torque telemetry volts -> torque
torque_to_volts = _equation("torque_range_nm", "volts_range")  # Eq 3 inverted: what the robot outputs


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
