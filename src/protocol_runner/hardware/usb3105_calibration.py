"""The USB-3105's factory calibration of its +-10 V outputs: stored (slope, offset) pairs and the code
they give for a voltage."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ChannelCalibration:
    """One channel's +-10 V factory calibration: ``code = round(slope * k + offset)``.

    `valid` is False when memory held no plausible pair (erased, NaN, slope far from 1); the driver then
    uses slope 1, offset 0 and says so in `calibration_summary`.
    """

    slope: float
    offset: float
    valid: bool = True


IDENTITY_CALIBRATION = ChannelCalibration(1.0, 0.0, valid=False)


def calibrated_code(volts: float, cal: ChannelCalibration) -> int:
    """The 16-bit code to send for `volts` on the +-10 V range: ``round(slope * k + offset)``, 0..65535,
    with the ideal code ``k = 32768 + 3276.8 * V``."""
    return min(65535, max(0, round(cal.slope * (32768.0 + 3276.8 * volts) + cal.offset)))


def parse_calibration(slope: float, offset: float) -> ChannelCalibration:
    """Accept a stored pair only when plausible (finite, slope within 20 % of 1, |offset| < 4096 counts)."""
    if math.isfinite(slope) and math.isfinite(offset) and 0.8 < slope < 1.2 and abs(offset) < 4096.0:
        return ChannelCalibration(float(slope), float(offset), valid=True)
    return IDENTITY_CALIBRATION
