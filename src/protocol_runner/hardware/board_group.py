"""Several input boards seen as one `AnalogInput` with global channel numbers (three USB-1608FS-Plus
give channels 0-23)."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.interfaces import AnalogInput, ScanBlock
from protocol_runner.hardware.usb1608fs_protocol import N_CHANNELS

log = logging.getLogger(__name__)


class BoardGroup:
    """Several input boards seen as one `AnalogInput` with global channel numbers.

    Global channel ``g`` is local channel ``g % channels_per_board`` of board ``g // channels_per_board``
    (boards in the order given; `open_all_1608fs` sorts them by serial number). Three USB-1608FS-Plus
    give channels 0-23.

    Alignment assumption: each board's pacer runs from its own crystal, started by its own AIN_SCAN_START a
    few milliseconds apart. Row ``i`` of every board is taken as simultaneous, with the time of board 0's
    row ``i``. The error is the start skew (typically 1-3 ms) plus the crystal drift (at most ~100 ppm
    between boards: 6.5 ms over a 65 s trial). For tighter alignment wire board 0's SYNC output to the
    others' SYNC inputs (external pacing, not implemented here). Rows that only some boards have delivered
    wait for the others; at `stop_scan` the rows beyond the shortest board are dropped (`dropped_rows`).
    """

    def __init__(self, boards: Sequence[AnalogInput], channels_per_board: int = N_CHANNELS) -> None:
        if not boards:
            raise InvalidInput("BoardGroup needs at least one board")
        self.boards = list(boards)
        self.channels_per_board = channels_per_board
        self._active: list[int] = []
        self._columns: list[tuple[int, int]] = []  # per requested channel: (board index, column in board)
        self._buffers: dict[int, list[ScanBlock]] = {}
        self._n_channels = 0
        self.dropped_rows = 0

    @property
    def n_channels(self) -> int:
        return self.channels_per_board * len(self.boards)

    @property
    def resolution_bits(self) -> int:
        return min(b.resolution_bits for b in self.boards)

    def locate(self, channel: int) -> tuple[int, int]:
        """(board index, local channel) of a global channel number."""
        if not 0 <= channel < self.n_channels:
            raise InvalidInput(
                f"input channel {channel} does not exist: {len(self.boards)} board(s) give channels "
                f"0-{self.n_channels - 1}"
            )
        return divmod(channel, self.channels_per_board)

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        chans = [int(c) for c in channels]
        if len(set(chans)) != len(chans):
            raise InvalidInput(f"scan channels must be distinct; got {chans}")
        per_board: dict[int, list[int]] = {}
        self._columns = []
        for g in chans:
            b, local = self.locate(g)
            lst = per_board.setdefault(b, [])
            self._columns.append((b, len(lst)))
            lst.append(local)
        self._active = sorted(per_board)
        self._buffers = {b: [] for b in self._active}
        self._n_channels = len(chans)
        self.dropped_rows = 0
        started: list[int] = []
        try:
            for b in self._active:
                self.boards[b].start_scan(per_board[b], rate_hz)
                started.append(b)
        except BaseException:
            for b in started:
                self.boards[b].stop_scan()
            raise

    def _collect(self, b: int, block: ScanBlock) -> None:
        if block.n_samples:
            self._buffers[b].append(block)

    def _emit(self, final: bool) -> ScanBlock:
        merged = {b: ScanBlock.concatenate(self._buffers[b], 0) for b in self._active if self._buffers[b]}
        if len(merged) < len(self._active):
            if final:
                self.dropped_rows = max((m.n_samples for m in merged.values()), default=0)
                self._buffers = {b: [] for b in self._active}
            return ScanBlock.empty(self._n_channels)
        n = min(m.n_samples for m in merged.values())
        codes = np.empty((n, self._n_channels), dtype=np.int32)
        volts = np.empty((n, self._n_channels), dtype=np.float64)
        for j, (b, col) in enumerate(self._columns):
            codes[:, j] = merged[b].codes[:n, col]
            volts[:, j] = merged[b].volts[:n, col]
        t_s = merged[self._active[0]].t_s[:n].copy()
        if final:
            self.dropped_rows = max(m.n_samples for m in merged.values()) - n
        for b, m in merged.items():
            rest = ScanBlock(t_s=m.t_s[n:], codes=m.codes[n:], volts=m.volts[n:])
            self._buffers[b] = [rest] if rest.n_samples and not final else []
        return ScanBlock(t_s=t_s, codes=codes, volts=volts)

    def read_available(self) -> ScanBlock:
        for b in self._active:
            self._collect(b, self.boards[b].read_available())
        return self._emit(final=False)

    def stop_scan(self) -> ScanBlock:
        errors: list[BaseException] = []
        for b in self._active:
            try:
                self._collect(b, self.boards[b].stop_scan())
            except Exception as exc:  # stop every board even when one fails
                errors.append(exc)
        if errors:
            raise errors[0]
        block = self._emit(final=True)
        if self.dropped_rows:
            log.info("BoardGroup: dropped %d unmatched trailing rows", self.dropped_rows)
        self._active = []
        return block

    def close(self) -> None:
        for b in self.boards:
            b.close()
