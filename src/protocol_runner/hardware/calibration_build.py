"""Build calibration tables from an observations file (docs/hardware-model.md).

Command line: ``python -m protocol_runner.hardware.calibration_build build OBSERVATIONS.csv --out-dir DIR``.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from protocol_runner.errors import InvalidInput, UserError, make_output_dir
from protocol_runner.hardware.calibration import (
    CalibrationTable,
    FloatArray,
    build_table_from_observations,
    build_torque_table_from_observations,
    write_calibration_table,
)
from protocol_runner.tables import parse_header_table, read_table_text

ANGLE_COLUMNS = ("input_deg", "real_deg", "output_deg")
TORQUE_COLUMNS = ("real_nm", "output_nm")
COMMENTS = {  # the first line of each table written
    "command": "Command look-up table (thesis §2.5.1): real joint angle wanted (deg) -> angle to command (deg).",
    "angle": "Angle telemetry look-up table (thesis §2.5.1): angle shown by the computer (deg) -> real "
    "joint angle (deg).",
    "torque": "Torque telemetry look-up table (thesis §2.5.2): torque shown by the computer (N*m) -> real "
    "torque (N*m).",
}


def _read_observations(path: Path) -> dict[str, FloatArray]:
    """Read an observations CSV: '#' comments, a header naming the columns, numeric rows."""
    text = read_table_text(path, "observations")
    table = parse_header_table(text)
    if table.header is None:
        raise InvalidInput(f"observations {path}: empty (no header row)")
    header = list(table.header.cells)
    rows: list[list[float]] = []
    for row in table.rows:
        lineno, cells, line = row.line, row.cells, row.text
        if len(cells) != len(header):
            raise InvalidInput(
                f"observations {path}, line {lineno}: expected {len(header)} values, found {len(cells)}"
            )
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise InvalidInput(f"observations {path}, line {lineno}: not a number: {line!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise InvalidInput(f"observations {path}, line {lineno}: values must be finite: {line!r}")
        rows.append(values)
    data = np.array(rows, dtype=np.float64).reshape(len(rows), len(header))
    return {name: data[:, i] for i, name in enumerate(header)}


def build_tables_from_file(observations: Path, out_dir: Path, prefix: str | None = None) -> list[Path]:
    """Build and write the tables an observations CSV supports; return the paths written.

    Columns ``input_deg, real_deg, output_deg`` give ``<prefix>_command.csv`` and ``<prefix>_angle.csv``;
    columns ``real_nm, output_nm`` give ``<prefix>_torque.csv``. `prefix` defaults to the file's stem
    without a trailing ``_observations``.
    """
    columns = _read_observations(observations)
    name = prefix or observations.stem.removesuffix("_observations")
    has_angle = all(c in columns for c in ANGLE_COLUMNS)
    has_torque = all(c in columns for c in TORQUE_COLUMNS)
    if not (has_angle or has_torque):
        raise InvalidInput(
            f"observations {observations}: needs columns {', '.join(ANGLE_COLUMNS)} (angle calibration) "
            f"or {', '.join(TORQUE_COLUMNS)} (torque calibration); found {', '.join(columns) or 'none'}"
        )
    make_output_dir(out_dir, "output directory")
    src = str(observations)
    tables: dict[str, CalibrationTable] = {}
    if has_angle:
        tables["command"], tables["angle"] = build_table_from_observations(
            columns["input_deg"], columns["real_deg"], columns["output_deg"], source=src
        )
    if has_torque:
        tables["torque"] = build_torque_table_from_observations(
            columns["real_nm"], columns["output_nm"], source=src
        )
    return [
        write_calibration_table(out_dir / f"{name}_{kind}.csv", table, f"{COMMENTS[kind]}\nBuilt from {src}.")
        for kind, table in tables.items()
    ]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m protocol_runner.hardware.calibration_build",
        description="Build calibration look-up tables (thesis §2.5) from calibration observations.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    build = sub.add_parser(
        "build",
        help="build look-up tables from an observations CSV",
        description=(
            "Read OBSERVATIONS (CSV, '#' comments allowed, header row first) with columns "
            "input_deg,real_deg,output_deg (angle calibration: commanded, real and displayed angle) and/or "
            "real_nm,output_nm (torque calibration: applied and displayed torque), and write "
            "PREFIX_command.csv (real_deg -> input_deg), PREFIX_angle.csv (output_deg -> real_deg) and/or "
            "PREFIX_torque.csv (output_nm -> real_nm) into --out-dir."
        ),
    )
    build.add_argument("observations", type=Path, metavar="OBSERVATIONS.csv")
    build.add_argument("--out-dir", type=Path, required=True, metavar="DIR", help="directory for the tables")
    build.add_argument(
        "--prefix",
        default=None,
        help="table name prefix, e.g. 'knee' (default: the observation file name without '_observations')",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m protocol_runner.hardware.calibration_build``; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        written = build_tables_from_file(args.observations, args.out_dir, args.prefix)
    except UserError as exc:
        print(f"error: {exc.message}", file=sys.stderr)
        return exc.exit_code
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
