"""The simulator's clock (simulated time, optionally paced like the rig) and its USB-3105 stand-in."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.usb3105_calibration import IDENTITY_CALIBRATION, calibrated_code

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

AO_CHANNELS = 16
"""USB-3105: 16 analog outputs (thesis §2.3)."""


class SimulatedClock:
    """Simulated time: `sleep_until` jumps instead of sleeping. With `realtime=True` it is the wall clock
    (time.monotonic from construction, plus `start_s`) and `sleep_until` really sleeps (`--realtime`)."""

    def __init__(self, *, realtime: bool = False, start_s: float = 0.0) -> None:
        self.realtime = realtime
        self._now_s = float(start_s)
        self._start_s = float(start_s)
        self._wall0 = time.monotonic()

    def now_s(self) -> float:
        if self.realtime:
            return self._start_s + (time.monotonic() - self._wall0)
        return self._now_s

    def sleep_until(self, t_s: float) -> None:
        if self.realtime:
            while True:
                remaining = t_s - self.now_s()
                if remaining <= 0.0:
                    return
                time.sleep(remaining)
        elif t_s > self._now_s:
            self._now_s = float(t_s)


def check_channel(channel: int, n_channels: int, board: str) -> int:
    if type(channel) is int and 0 <= channel < n_channels:
        return channel
    if (
        isinstance(channel, bool)
        or not isinstance(channel, int | np.integer)
        or not 0 <= channel < n_channels
    ):
        raise InvalidInput(f"{board}: channel must be an integer 0-{n_channels - 1}, got {channel!r}")
    return int(channel)


def _ao_code(volts: float) -> int:
    """The code a USB-3105 sends for `volts` on the ±10 V range with ideal calibration: the board driver's
    own scalar rule (`usb3105_calibration.calibrated_code`, equal to `conversions.volts_to_ao16_code`)."""
    v = float(volts)
    if math.isnan(v):
        raise InvalidInput("USB-3105 (simulated): cannot output NaN volts")
    if math.isinf(v):
        return 65535 if v > 0.0 else 0
    return calibrated_code(v, IDENTITY_CALIBRATION)


class SimulatedAnalogOutput:
    """A USB-3105 stand-in: quantises volts to its 16-bit ±10 V ideal code (clamped) and records every
    update as (time, channel, code). The simulated robot (`listen`) reads the updates written since it last
    looked when it is about to move (`deliver`, before every integration): a write costs a few list
    appends, and the robot decodes a whole read's worth of them at once."""

    def __init__(self, clock: SimulatedClock) -> None:
        self._clock = clock
        self._listeners: list[Callable[[FloatArray, IntArray, IntArray], None]] = []
        self._t: list[float] = []
        self._channel: list[int] = []
        self._code: list[int] = []
        self._delivered = 0
        self._closed = False

    def listen(self, listener: Callable[[FloatArray, IntArray, IntArray], None]) -> None:
        """Hand `listener` every update from now on, as (time_s, channel, code) arrays (`deliver`)."""
        self._listeners.append(listener)

    def deliver(self) -> None:
        """Hand the updates recorded since the last delivery to the listeners, in time order."""
        first = self._delivered
        if first == len(self._t):
            return
        self._delivered = len(self._t)
        t, channel, code = self._arrays(first)
        for listener in self._listeners:
            listener(t, channel, code)

    def _arrays(self, first: int) -> tuple[FloatArray, IntArray, IntArray]:
        return (
            np.asarray(self._t[first:], dtype=np.float64),
            np.asarray(self._channel[first:], dtype=np.int64),
            np.asarray(self._code[first:], dtype=np.int64),
        )

    def _emit(self, t_s: float, channel: int, code: int) -> None:
        self._t.append(t_s)
        self._channel.append(channel)
        self._code.append(code)

    def configure_channel(self, channel: int) -> None:
        """±10 V range; like the real board this also drives the output to 0 V (code 32768)."""
        ch = check_channel(channel, AO_CHANNELS, "USB-3105 (simulated)")
        self._emit(self._clock.now_s(), ch, 32768)

    def write_volts(self, channel: int, volts: float) -> int:  # hot path: one call per output tick
        ch = (
            channel
            if type(channel) is int and 0 <= channel < AO_CHANNELS
            else check_channel(channel, AO_CHANNELS, "USB-3105 (simulated)")
        )
        # `_ao_code` inlined for the usual in-range value (NaN, infinities and clamping take the full rule)
        if type(volts) is float and 0.0 <= (k := 32768.0 + 3276.8 * volts) <= 65535.0:
            code = round(k)
        else:
            code = _ao_code(volts)
        self._t.append(self._clock.now_s())
        self._channel.append(ch)
        self._code.append(code)
        return code

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        t_s = self._clock.now_s()
        codes: dict[int, int] = {}
        for channel, volts in volts_by_channel.items():
            ch = check_channel(channel, AO_CHANNELS, "USB-3105 (simulated)")
            codes[ch] = _ao_code(volts)
        for ch, code in codes.items():
            self._emit(t_s, ch, code)
        return codes

    def records(self) -> tuple[FloatArray, npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Every update since the last `clear_records`: (time_s, channel, code) arrays."""
        return self._arrays(0)

    def clear_records(self) -> None:
        """Deliver what the listeners have not read yet, then forget every update."""
        self.deliver()
        self._t.clear()
        self._channel.clear()
        self._code.clear()
        self._delivered = 0

    def close(self) -> None:
        self._closed = True
