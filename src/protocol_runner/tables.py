"""The one reader of header-plus-table text files: calibration tables, observations, trajectory files,
reference datasets.

Format: lines starting with `#` are comments; blank lines are skipped; the first other line names the
columns; every later line is one row. Cells are comma-separated (CSV quoting allowed) and stripped. What
the columns must be, and the messages about them, are the caller's: this module only splits the text,
keeping each line's number for those messages.
"""

from __future__ import annotations

import csv
import math
import stat
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from .errors import InvalidInput


class Row(NamedTuple):
    """One non-comment line (a tuple: a recorded trajectory has tens of thousands of them)."""

    line: int  # 1-based line number in the file
    cells: tuple[str, ...]
    text: str  # the whole line, stripped


@dataclass(frozen=True)
class HeaderTable:
    comments: tuple[str, ...]  # the comment lines, without `#` and surrounding blanks
    header: Row | None  # None: the text has no line but comments and blanks
    rows: tuple[Row, ...]

    @property
    def lines(self) -> tuple[Row, ...]:
        """The header row followed by the data rows."""
        return ((self.header,) if self.header is not None else ()) + self.rows


def parse_header_table(text: str) -> HeaderTable:
    comments: list[str] = []
    rows: list[Row] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            comments.append(line.lstrip("#").strip())
            continue
        rows.append(Row(number, _cells(line), line))
    return HeaderTable(tuple(comments), rows[0] if rows else None, tuple(rows[1:]))


def _cells(line: str) -> tuple[str, ...]:
    """The line's stripped cells. Without a quote (or NUL) CSV splitting is splitting at every comma, done
    here directly: the csv module is only needed for quoted cells."""
    if '"' in line or "\x00" in line:
        return tuple(c.strip() for c in next(csv.reader([line])))
    return tuple(map(str.strip, line.split(",")))


def number_columns(
    table: HeaderTable, columns: Sequence[int], bad_row: Callable[[Row], str]
) -> list[list[float]]:
    """The data rows' cells in `columns` (indices into the cells) as numbers: one list per column, in row
    order. `InvalidInput` with the caller's `bad_row(row)` message at the first row whose cell is missing
    or not a number."""
    try:  # one column at a time; the rows are only walked in order to name a bad one
        return [[float(row.cells[c]) for row in table.rows] for c in columns]
    except (IndexError, ValueError):
        pass
    out: list[list[float]] = [[] for _ in columns]
    for row in table.rows:
        try:
            values = [float(row.cells[c]) for c in columns]
        except (IndexError, ValueError):
            raise InvalidInput(bad_row(row)) from None
        for column, value in zip(out, values, strict=True):
            column.append(value)
    return out


def finite_numbers(row: Row, where: str) -> list[float]:
    """The row's cells as finite numbers, or `InvalidInput` starting with `where` (the file and line)."""
    try:
        values = [float(c) for c in row.cells]
    except ValueError:
        raise InvalidInput(f"{where}: not a number: {row.text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise InvalidInput(f"{where}: values must be finite numbers, found {row.text!r}")
    return values


MAX_TABLE_BYTES = 64 * 2**20
"""The largest table file read (a trajectory, a calibration table, a reference dataset): 64 MiB holds about
3.9 million rows of "12.345,45.678901", an hour of samples at 1 kHz. Parsed, a table takes about 30 times
its size in memory, so a larger file is refused before it is read."""


def read_table_text(path: Path, what: str, max_bytes: int = MAX_TABLE_BYTES) -> str:
    """The file's UTF-8 text (a leading byte-order mark removed), or `InvalidInput` naming `what` and
    `path`. A FIFO or a device is refused unread (its read would wait forever, or never end)."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise InvalidInput(f"{what} {path}: file not found") from None
    except OSError as exc:
        raise InvalidInput(f"{what} {path}: cannot read it ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise InvalidInput(
            f"{what} {path}: not a regular file (a directory, a FIFO or a device); give a file"
        )
    if info.st_size > max_bytes:
        raise InvalidInput(
            f"{what} {path}: {info.st_size} bytes, more than the {max_bytes} ({max_bytes >> 20} MiB) a table "
            "may have; it is not read"
        )
    try:
        with path.open("rb") as f:
            raw = f.read(max_bytes + 1)
        if len(raw) > max_bytes:
            raise InvalidInput(f"{what} {path}: more than {max_bytes} bytes; it is not read")
        return raw.decode("utf-8-sig")  # a leading byte-order mark (spreadsheet exports) is not data
    except FileNotFoundError:
        raise InvalidInput(f"{what} {path}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"{what} {path}: cannot read it ({exc})") from None
