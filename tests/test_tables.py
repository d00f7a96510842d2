"""The one header-plus-table reader: comments, header, rows, with the file's line numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from protocol_runner.analysis.reference import load_reference_dataset
from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.calibration import load_calibration_table
from protocol_runner.protocol.trajectories import load_trajectory_file
from protocol_runner.tables import number_columns, parse_header_table

TEXT = '# made by hand\n\n  # second note\ntime_s, angle_deg\n0, 1.5\n\n1,"2.5"\n'


def test_comments_header_and_rows_keep_their_line_numbers() -> None:
    table = parse_header_table(TEXT)
    assert table.comments == ("made by hand", "second note")
    assert table.header is not None
    assert (table.header.line, table.header.cells) == (4, ("time_s", "angle_deg"))
    assert [(r.line, r.cells) for r in table.rows] == [(5, ("0", "1.5")), (7, ("1", "2.5"))]


def test_number_columns_reads_the_asked_columns_in_the_asked_order() -> None:
    table = parse_header_table("a, b, c\n1, 2, 3\n4, 5, 6\n")
    assert number_columns(table, (2, 0), str) == [[3.0, 6.0], [1.0, 4.0]]


@pytest.mark.parametrize("row", ["7, x, 9", "7, 8"])
def test_number_columns_names_the_first_row_that_is_not_numbers(row: str) -> None:
    table = parse_header_table(f"a, b, c\n1, 2, 3\n{row}\n4, 5, 6\n")
    with pytest.raises(InvalidInput, match=rf"^line 3: {row}$"):
        number_columns(table, (0, 2) if row == "7, 8" else (1,), lambda r: f"line {r.line}: {r.text}")


def test_only_comments_is_a_table_without_header() -> None:
    table = parse_header_table("# nothing\n\n")
    assert table.header is None and table.rows == () and table.lines == ()


@pytest.mark.parametrize(
    "name, load",
    [
        ("table.csv", load_calibration_table),
        ("trajectory.csv", load_trajectory_file),
        ("reference.csv", load_reference_dataset),
    ],
)
def test_every_reader_names_the_file_line_of_a_bad_row(tmp_path: Path, name: str, load) -> None:
    """The three readers share the splitting: a bad number on line 6 is reported as line 6."""
    header = (
        "real_deg,input_deg"
        if name == "table.csv"
        else "time_s,angle_deg"
        if name == "trajectory.csv"
        else "angle_deg,torque_nm"
    )
    path = tmp_path / name
    path.write_text(f"# note\n{header}\n0,0\n1,1\n\n2,x\n", encoding="utf-8")
    with pytest.raises(InvalidInput) as info:
        load(path)
    assert "6" in info.value.message and str(path) in info.value.message


def test_the_first_bad_row_is_named_whichever_column_it_is_bad_in() -> None:
    """Columns are converted one at a time (fast); the message still names the first bad row of the file."""
    table = parse_header_table("a, b, c\n1, 2, 3\n4, 5, x\ny, 8, 9\n")
    with pytest.raises(InvalidInput, match=r"^line 3: 4, 5, x$"):
        number_columns(table, (0, 2), lambda r: f"line {r.line}: {r.text}")


def test_quoted_cells_are_split_as_csv_and_plain_ones_at_every_comma() -> None:
    table = parse_header_table('name, value\n"a, b", 1\n  c ,2 \n')
    assert [r.cells for r in table.rows] == [("a, b", "1"), ("c", "2")]


def test_a_trajectory_saved_with_a_byte_order_mark_reads_as_without(tmp_path: Path) -> None:
    """Spreadsheets save CSV with a UTF-8 byte-order mark; it was read into the first header cell and the
    file refused (its message showing the right header). It is not data."""
    text = "time_s,angle_deg\n0,10\n1,20\n2,15\n"
    plain, marked = tmp_path / "plain.csv", tmp_path / "marked.csv"
    plain.write_bytes(text.encode("utf-8"))
    marked.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    a, b = load_trajectory_file(marked), load_trajectory_file(plain)
    assert a.column == b.column == "angle_deg"
    assert np.array_equal(a.time_s, b.time_s) and np.array_equal(a.angle_deg, b.angle_deg)
