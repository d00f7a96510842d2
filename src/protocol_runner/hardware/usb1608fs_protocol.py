"""The USB-1608FS-Plus's USB protocol facts (from public sources; docs/hardware.md): ids, commands,
status bits and the pacer clock (its +-10 V codes: `conversions.ai16_code_to_volts`).

Protocol (reference "USB facts"; vendor control transfers bmRequestType 0xC0 in / 0x40 out, wIndex 0):

- ``0x14`` AIN_CONFIG (out): 8 range bytes, one per channel (0 = +-10 V).
- ``0x11`` AIN_SCAN_START (out): ``<u32 count (0 = continuous), u32 pacer = 40 MHz / rate - 1, u8 channel
  mask, u8 options>``; rows come in ascending channel order.
- ``0x12`` AIN_SCAN_STOP, ``0x15`` AIN_CLR_FIFO (out); ``0x44`` STATUS (in, u16: bit 1 running, bit 2
  overrun; an overrun stalls the bulk pipe); ``0x48`` serial (in, 8 ASCII bytes); ``0x41`` blink (out).
- ``0x30`` calibration memory (in, wValue = address): float32 LE (slope, intercept) for every range and
  channel, ranges outer, channels inner, from address 0; ``calibrated = raw * slope + intercept``.
- Scan data: bulk IN 0x81, 64-byte packets of LE u16 codes; +-10 V: ``V = (k - 32768) * 10 / 32768``.
"""

from __future__ import annotations

PRODUCT_ID = 0x00EA
KIND = "USB-1608FS-Plus"
N_CHANNELS = 8
N_RANGES = 8
RANGE_PM10V = 0
PACER_CLOCK_HZ = 40_000_000.0
MAX_RATE_HZ = 100_000.0

REQ_IN = 0xC0
REQ_OUT = 0x40
CMD_AIN_SCAN_START = 0x11
CMD_AIN_SCAN_STOP = 0x12
CMD_AIN_CONFIG = 0x14
CMD_AIN_CLR_FIFO = 0x15
CMD_CAL_MEMORY = 0x30
CMD_BLINK_LED = 0x41
CMD_STATUS = 0x44
CMD_SERIAL = 0x48

STATUS_OVERRUN = 0x04


def pacer_period(rate_hz: float) -> int:
    """The pacer register for `rate_hz` rows per second: ``round(40 MHz / rate - 1)``."""
    return round(PACER_CLOCK_HZ / rate_hz - 1.0)


def pacer_rate_hz(pacer: int) -> float:
    """The row rate a pacer register value really gives: ``40 MHz / (pacer + 1)``."""
    return PACER_CLOCK_HZ / (pacer + 1)
