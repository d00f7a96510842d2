"""What the vendor-library backends (`uldaq_boards.py`, `mcculw_boards.py`) share: loading MCC's library
lazily with a plain message when it is missing, the ±10 V code of a voltage, the grouping of output
channels into the contiguous runs a synchronous update takes, and the reader of a continuous scan's
circular buffer.

Both libraries apply the boards' calibration themselves and hand back volts: the codes these backends
report are the ideal 16-bit codes of those volts on the ±10 V range (``k = 32768 + 3276.8 V``,
`conversions.volts_to_ao16_code` / `volts_to_ai16_code`), the same scale as the pyusb drivers' codes.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import math
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import partial
from types import ModuleType
from typing import Any, Self, TypeVar

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import HardwareUnavailable, InvalidInput
from protocol_runner.hardware import usb1608fs_protocol, usb3105
from protocol_runner.hardware.conversions import VOLTS_RANGE, volts_to_ai16_code, volts_to_ao16_code
from protocol_runner.hardware.interfaces import Clock, ScanBlock
from protocol_runner.hardware.usb_common import (
    DRY_RUN_HINT,
    BoardIoError,
    BoardNotFound,
    ScanOverrun,
    check_scan_channels,
    finite_volts,
    output_channel,
)

log = logging.getLogger(__name__)
T = TypeVar("T")


class VendorLibraryMissing(InvalidInput):
    """A rig file names a vendor backend whose library is not installed (exit 2: a setup choice to fix)."""


def import_vendor(module: str, backend: str, native: str) -> ModuleType:
    """Import MCC's Python package for `backend` (``uldaq`` or ``mcculw``), or say how to install it.

    `native` names the system library the Python package loads when imported (libuldaq, the UL's
    cbw64.dll): a package that is installed but fails to import (that library missing, or mcculw on a
    system other than Windows) gets its own message.
    """
    if not _installed(backend):
        raise VendorLibraryMissing(
            f"the rig file selects backend: {backend}, but the Python package {backend!r} is not installed. "
            f"Install it with: pip install protocol-runner[{backend}] (and {native}: docs/hardware.md, "
            '"The path to the rig"), or set backend: pyusb for this board in the rig file.'
        )
    try:
        return importlib.import_module(module)
    except Exception as exc:  # the package's own import failed: OSError, or NameError off Windows
        raise VendorLibraryMissing(
            f"the rig file selects backend: {backend}: the Python package {backend!r} is installed but could "
            f"not load {native} ({type(exc).__name__}: {exc}). Install {native} (docs/hardware.md, "
            '"The path to the rig"), or set backend: pyusb for this board in the rig file.'
        ) from None


def _installed(package: str) -> bool:
    """Whether `package` is imported already or can be found, without importing it."""
    if package in sys.modules:
        return sys.modules[package] is not None
    return importlib.util.find_spec(package) is not None


def of_kind(found: Iterable[Any], product_id: int) -> list[Any]:
    """The library's device descriptors of one board kind (USB product id), sorted by serial number."""
    return sorted((d for d in found if int(d.product_id) == product_id), key=lambda d: str(d.unique_id))


def pick(found: list[Any], serial: str | None, kind: str, library: str, hint: str) -> Any:
    """The descriptor with `serial` (or the first); `BoardNotFound` naming what `library` saw otherwise,
    with `hint` of what to check."""
    for d in found:
        if serial is None or str(d.unique_id) == serial:
            return d
    seen = ", ".join(str(d.unique_id) for d in found) or "none"
    wanted = f" with serial {serial}" if serial else ""
    raise BoardNotFound(
        f"{library} found no {kind}{wanted} (boards of that kind attached: {seen}); is it {hint}? "
        f"{DRY_RUN_HINT}"
    )


def checked_volts(channel: int, volts: float) -> float:
    """A finite output voltage, clamped to ±10 V (as the pyusb driver clamps its code)."""
    return min(VOLTS_RANGE[1], max(VOLTS_RANGE[0], finite_volts(channel, volts)))


def contiguous_runs(channels: Sequence[int]) -> list[list[int]]:
    """Sorted channels split into runs of consecutive numbers: ``[8, 9, 11] -> [[8, 9], [11]]``.

    Both libraries update a contiguous channel range together (uldaq `a_out_list`, mcculw `a_out_scan`
    with SIMULTANEOUS); a channel between two driven ones belongs to another joint and is never written.
    """
    runs: list[list[int]] = []
    for ch in sorted(channels):
        if runs and ch == runs[-1][-1] + 1:
            runs[-1].append(ch)
        else:
            runs.append([ch])
    return runs


class VendorBoard:
    """What both vendor boards share: a name and serial, and each library call made through `_call`, which
    turns the library's exception into the `HardwareUnavailable` the backend's `map_error(exc, action)`
    names (an exception it does not recognise is raised as it is). The backend also gives how to let the
    board go (`release`) and to flash its LED (`flash_led(count)`)."""

    def __init__(
        self,
        name: str,
        serial: str,
        *,
        release: Callable[[], None],
        map_error: Callable[[Exception, str], HardwareUnavailable | None],
        flash_led: Callable[[int], None],
    ) -> None:
        self.name = name
        self._serial = serial
        self._closed = False
        self._release, self._map_error, self._flash_led = release, map_error, flash_led

    def blink(self, count: int = 5) -> None:
        self._call("blinking the LED", lambda: self._flash_led(count))

    def _before_release(self) -> None:
        """Stop what the board has running before it is let go (nothing by default)."""
        return None

    def close(self) -> None:
        """Let the board go (idempotent); an output board's outputs keep their last value."""
        if self._closed:
            return
        self._before_release()
        try:
            self._call("closing the board", self._release)
        finally:
            self._closed = True

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def serial(self) -> str:
        return self._serial

    def _call(self, action: str, fn: Callable[[], T]) -> T:
        try:
            return fn()
        except Exception as exc:
            mapped = self._map_error(exc, action)
            if mapped is None:
                raise
            raise mapped from exc


class VendorScanInput(VendorBoard, ABC):
    """An `AnalogInput` over a vendor library's continuous background scan (one board, 8 channels ±10 V).

    The libraries scan a contiguous channel range ``low..high``: the scan covers the lowest to the highest
    channel asked for and keeps the asked ones, in the asked order. Row ``i`` is at ``t0 + i / rate``,
    ``rate`` being the rate the library reports it set and ``t0`` the clock around the call that started
    the scan. The scan's circular buffer holds `buffer_s` seconds: a read later than that is a
    `ScanOverrun`. A failure while reading stops the scan before the error goes on; `stop_scan` and
    `close` stop it too.

    A backend implements `_start_scan` (start it, return the rate set), `_scan_status` (running?,
    samples transferred so far), `_stop`, `_copy(first, count)` (`count` samples from buffer position
    `first`, never across its end) and `_free_buffer`.
    """

    kind = usb1608fs_protocol.KIND
    n_channels = usb1608fs_protocol.N_CHANNELS
    channels_per_board = usb1608fs_protocol.N_CHANNELS
    status_after_stop = True
    """Whether the scan status still counts the samples after the stop (then they are collected too)."""

    def __init__(self, name: str, serial: str, clock: Clock, buffer_s: float, **backend: Any) -> None:
        super().__init__(name, serial, **backend)
        self.clock = clock
        self.buffer_s = buffer_s
        self._scanning = False
        self._columns: npt.NDArray[np.intp] = np.zeros(0, dtype=np.intp)
        self._rate_hz = 0.0
        self._t0 = 0.0
        self._rows_emitted = 0
        self._ring_size = 0  # samples the circular buffer holds
        self._width = 0  # samples per buffer row (the channels low..high)
        self._taken = 0  # samples taken out of it so far (whole rows only)

    @abstractmethod
    def _start_scan(self, low: int, high: int, rows: int, rate_hz: float) -> float: ...

    @abstractmethod
    def _scan_status(self) -> tuple[bool, int]: ...

    @abstractmethod
    def _stop(self) -> None: ...

    @abstractmethod
    def _copy(self, first: int, count: int) -> npt.NDArray[np.float64]: ...

    @abstractmethod
    def _free_buffer(self) -> None: ...

    @property
    def resolution_bits(self) -> int:
        return 16

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        """Start a continuous scan of `channels` (0-7, any order) at `rate_hz` rows per second."""
        chans = check_scan_channels(self.kind, channels, self.n_channels, rate_hz)
        if self._closed:
            raise InvalidInput(f"the {self.name} is closed; open it again")
        if self._scanning:
            raise InvalidInput(f"the {self.name} is already scanning; stop_scan() first")
        low, high = min(chans), max(chans)
        width = high - low + 1
        rows = max(1, math.ceil(rate_hz * self.buffer_s))
        self._columns = np.array([c - low for c in chans], dtype=np.intp)
        self._rows_emitted = 0
        before = self.clock.now_s()
        try:
            self._rate_hz = float(
                self._call("starting the scan", lambda: self._start_scan(low, high, rows, rate_hz))
            )
        except BaseException:
            self._abandon()  # a buffer allocated for a scan that did not start is freed
            raise
        after = self.clock.now_s()
        self._t0 = 0.5 * (before + after)
        self._ring_size, self._width, self._taken = rows * width, width, 0
        self._scanning = True

    def _block(self, rows: npt.NDArray[np.float64]) -> ScanBlock:
        volts = np.ascontiguousarray(rows[:, self._columns])
        n = volts.shape[0]
        t_s = self._t0 + (self._rows_emitted + np.arange(n, dtype=np.float64)) / self._rate_hz
        self._rows_emitted += n
        return ScanBlock(t_s=t_s, codes=volts_to_ai16_code(volts), volts=volts)

    def _take(self, *, stopping: bool = False) -> npt.NDArray[np.float64]:
        running, total = self._call("reading the scan status", self._scan_status)
        rows = self._new_rows(total)
        if not running and not stopping:
            raise BoardIoError(
                f"the {self.name} scan stopped by itself after {self._taken} samples; "
                "unplug and replug the board, then redo the trial."
            )
        return rows

    def _new_rows(self, total: int) -> npt.NDArray[np.float64]:
        """The complete rows, shape (rows, width), among the first `total` samples of the scan that were
        not taken yet, out of the circular buffer in order.

        The library writes sample ``k`` of the scan (counting from 0 at the start, channels interleaved) at
        buffer position ``k mod size``. When more than a buffer's worth arrived since the last take, the
        oldest were overwritten before they were read: that is a `ScanOverrun`, never silently lost rows.
        """
        total -= total % self._width
        new = total - self._taken
        if new < 0:
            raise ScanOverrun(
                f"the {self.name} reported {total} samples after {self._taken} were read; the scan count went "
                "backwards. Unplug and replug the board, then redo the trial."
            )
        if new > self._ring_size:
            raise ScanOverrun(
                f"the {self.name} scan overran its buffer: {new} samples arrived since the last read, the "
                f"buffer holds {self._ring_size}. The computer did not read the data fast enough: close other "
                "programs or lower the input rate; the trial is marked failed and can be redone."
            )
        if new == 0:
            return np.zeros((0, self._width))
        start = self._taken % self._ring_size
        first = min(new, self._ring_size - start)
        parts = [self._copy(start, first)]
        if new > first:  # the samples wrapped round the end of the buffer
            parts.append(self._copy(0, new - first))
        self._taken = total
        return np.concatenate(parts).reshape(-1, self._width)

    def read_available(self) -> ScanBlock:
        """Every complete row acquired since the last call (calibrated volts, their codes, times)."""
        if not self._scanning:
            return ScanBlock.empty(len(self._columns))
        try:
            rows = self._take()
        except BaseException:
            self._abandon()
            raise
        return self._block(rows)

    def stop_scan(self) -> ScanBlock:
        """Stop the scan and return the rows not read yet."""
        if not self._scanning:
            return ScanBlock.empty(len(self._columns))
        try:
            rows = [self._take(stopping=True)]
            self._call("stopping the scan", self._stop)
            if self.status_after_stop:
                rows.append(self._take(stopping=True))  # what the library moved in while it stopped
        except BaseException:
            self._abandon()
            raise
        self._scanning = False
        self._call("freeing the scan buffer", self._free_buffer)
        return self._block(np.concatenate(rows))

    def _abandon(self) -> None:
        """Stop the scan after a failure, never hiding the failure."""
        self._scanning = False
        for what in (self._stop, self._free_buffer):
            try:
                what()
            except Exception:
                log.warning("%s: could not stop the scan after a failure", self.name)

    def _before_release(self) -> None:
        if self._scanning:
            self._abandon()


class VendorAnalogOutput(VendorBoard, ABC):
    """An `AnalogOutput` over a vendor library (the USB-3105: 16 channels, ±10 V, software-paced).

    `configure_channel` writes 0 V on the ±10 V range once (the library sends the board's range command,
    which also drives the pin to 0 V); writing an unconfigured channel is refused, as with the pyusb
    driver. `write_volts_sync` updates each contiguous run of channels together (`contiguous_runs`).
    The codes returned are the ideal codes of the volts written (the library applies the calibration).
    A backend implements `_write` and `_write_run`.
    """

    kind = usb3105.KIND
    n_channels = usb3105.N_CHANNELS

    def __init__(self, name: str, serial: str, **backend: Any) -> None:
        super().__init__(name, serial, **backend)
        self._configured: set[int] = set()

    @abstractmethod
    def _write(self, channel: int, volts: float) -> None: ...

    @abstractmethod
    def _write_run(self, low: int, volts: Sequence[float]) -> None: ...

    def _call(self, action: str, fn: Callable[[], T]) -> T:
        if self._closed:
            raise BoardIoError(f"the {self.name} is closed; open it again")
        return super()._call(action, fn)

    def _checked(self, channel: int, volts: float) -> float:
        ch = output_channel(self.kind, channel, self.n_channels)
        if ch not in self._configured:
            raise InvalidInput(
                f"output channel {ch} of the {self.name} is not configured: call configure_channel() once "
                "before writing (it sets +-10 V and drives the pin to 0 V)"
            )
        return checked_volts(ch, volts)

    def configure_channel(self, channel: int) -> None:
        """Set `channel` to ±10 V and 0 V. This drives the pin to 0 V: call once before a run."""
        ch = output_channel(self.kind, channel, self.n_channels)
        self._call(f"configuring output channel {ch}", lambda: self._write(ch, 0.0))
        self._configured.add(ch)

    def write_volts(self, channel: int, volts: float) -> int:
        """Output `volts` on `channel` now; return its ±10 V code."""
        v = self._checked(channel, volts)
        self._call(f"writing output channel {channel}", lambda: self._write(channel, v))
        return int(volts_to_ao16_code(v))

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        """Output several channels: each contiguous run of channels updated together."""
        volts = {ch: self._checked(ch, v) for ch, v in volts_by_channel.items()}
        for run in contiguous_runs(list(volts)):
            self._call(
                f"writing output channels {run[0]}-{run[-1]}",
                partial(self._write_run, run[0], [volts[ch] for ch in run]),
            )
        return {ch: int(volts_to_ao16_code(v)) for ch, v in volts.items()}
