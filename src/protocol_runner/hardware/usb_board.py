"""The life of an opened USB board, shared by the three drivers: set-up that releases the interface if it
fails, and an idempotent `close` (also on leaving ``with board:``)."""

from __future__ import annotations

from dataclasses import dataclass
from types import TracebackType
from typing import Any, Generic, Self, TypeVar

import usb.core

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.usb_common import BoardIoError, bcd_to_text, release_device, usb_call


@dataclass(frozen=True)
class TransportSettings:
    """What every board's transport settings hold: the interface it claims, the timeout of one command."""

    interface: int = 0
    timeout_ms: int = 1000


@dataclass(frozen=True)
class InPipeSettings(TransportSettings):
    """A board whose data comes back on one IN endpoint (the MCC boards): its address and packet size, and
    how the stale data left in it is drained (at most `max_drain_packets` reads, each `drain_timeout_ms`)."""

    in_endpoint: int = 0x81
    packet_size: int = 64
    drain_timeout_ms: int = 20
    max_drain_packets: int = 256


SettingsT = TypeVar("SettingsT", bound=TransportSettings)


class OpenedBoard(Generic[SettingsT]):
    """The closing every opened USB board shares: `close` releases the claimed interface once (idempotent;
    a board whose `_before_release` stops something running overrides that hook), and ``with board:``
    closes it on the way out. A board sets `_dev`, `settings`, `name` and ``_closed = False`` when it
    opens."""

    _dev: usb.core.Device
    settings: SettingsT
    name: str
    _closed: bool

    def _usb(self, action: str, fn: Any, *args: Any) -> Any:
        """One pyusb call on the open board, its failure mapped (`usb_call`)."""
        if self._closed:
            raise BoardIoError(f"the {self.name} is closed; open it again")
        return usb_call(self.name, action, fn, *args)

    @property
    def firmware(self) -> str:
        """Firmware version from bcdDevice, e.g. ``"1.02"``."""
        return bcd_to_text(int(self._dev.bcdDevice))

    @staticmethod
    def _check_blink(count: int) -> None:
        if not 0 < count < 256:
            raise InvalidInput(f"blink count must be 1-255, got {count}")

    def _setup(self) -> None:
        """Claim and configure the freshly opened board, read its calibration (each driver's own)."""
        raise NotImplementedError

    def _set_up(self) -> Self:
        """Run `_setup`; on any failure release the interface and free the device before the error
        propagates, so that the board can be opened again. Returns the board."""
        try:
            self._setup()
        except BaseException:
            release_device(self._dev, self.settings.interface)
            raise
        return self

    def _before_release(self) -> None:
        """Stop what the board has running before its interface is released (nothing by default)."""

    def close(self) -> None:
        """Release the interface (idempotent)."""
        if self._closed:
            return
        self._before_release()
        self._closed = True
        release_device(self._dev, self.settings.interface)

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
