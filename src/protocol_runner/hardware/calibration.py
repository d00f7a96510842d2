"""Calibration look-up tables (thesis §2.5, docs/hardware-model.md §3): piecewise-linear, strictly monotonic
maps loaded from CSV.

Per joint: the *command* table ``real_deg -> input_deg``, applied before sending; the *angle* table
``output_deg -> real_deg`` and the *torque* table ``output_nm -> real_nm``, applied to telemetry. They are
built from calibration observations (α_input commanded, α_real read on the joint's marked scale, α_output
shown by the computer) by `build_table_from_observations`, or ``python -m
protocol_runner.hardware.calibration_build build OBS.csv --out-dir DIR``.

CSV format (read by `load_calibration_table`, written by `write_calibration_table`)::

    # any number of comment lines starting with '#': what the table maps, units, origin
    real_deg,input_deg          <- header row: the two column names (x first)
    0.0,0.0                     <- at least two rows of finite numbers, x strictly increasing,
    5.0,3.21                       y strictly monotonic (so the table can be inverted)

Between points the table interpolates linearly; beyond its ends it extrapolates with the end segments (it
never clamps: a value outside the calibrated span stays visible, and the map stays invertible).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.tables import parse_header_table, read_table_text

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CalibrationTable:
    """A strictly monotonic piecewise-linear map y(x) (thesis §2.5 "look-up table").

    `x` is strictly increasing, `y` strictly increasing or strictly decreasing, both finite, at least two
    points. `x_name`/`y_name` name the columns with their units (e.g. ``real_deg``); `source` says where
    the table came from (a file path, or "inverse of ...").
    """

    x: FloatArray
    y: FloatArray
    x_name: str
    y_name: str
    source: str = field(default="(in memory)")

    def __post_init__(self) -> None:
        x = np.array(self.x, dtype=np.float64)
        y = np.array(self.y, dtype=np.float64)
        problem = _table_problem(x, y)
        if problem is not None:
            raise InvalidInput(f"calibration table {self.source}: {problem}")
        x.setflags(write=False)
        y.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)

    @property
    def n_points(self) -> int:
        return int(self.x.shape[0])

    def __call__(self, x: npt.ArrayLike) -> FloatArray:
        """Map `x` through the table: linear interpolation inside, linear extrapolation outside."""
        values = np.asarray(x, dtype=np.float64)
        out = np.interp(values, self.x, self.y)
        below = values < self.x[0]
        above = values > self.x[-1]
        if below.any() or above.any():
            slope_lo = (self.y[1] - self.y[0]) / (self.x[1] - self.x[0])
            slope_hi = (self.y[-1] - self.y[-2]) / (self.x[-1] - self.x[-2])
            out = np.where(below, self.y[0] + (values - self.x[0]) * slope_lo, out)
            out = np.where(above, self.y[-1] + (values - self.x[-1]) * slope_hi, out)
        result: FloatArray = np.asarray(out, dtype=np.float64)
        return result

    def inverse(self) -> CalibrationTable:
        """The table of x(y): same points, columns swapped (exact inverse, extrapolation included)."""
        order = np.argsort(self.y)
        return CalibrationTable(
            x=self.y[order],
            y=self.x[order],
            x_name=self.y_name,
            y_name=self.x_name,
            source=f"inverse of {self.source}",
        )


def _table_problem(x: FloatArray, y: FloatArray) -> str | None:
    """Describe what makes (x, y) an invalid table, or None."""
    if x.ndim != 1 or y.ndim != 1 or x.shape != y.shape:
        return f"x and y must be 1-D arrays of the same length, got shapes {x.shape} and {y.shape}"
    if x.shape[0] < 2:
        return f"needs at least 2 points, got {x.shape[0]}"
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        return "contains NaN or infinite values"
    dx = np.diff(x)
    if not (dx > 0).all():
        i = int(np.argmax(dx <= 0))
        return f"x must be strictly increasing, but point {i + 2} ({x[i + 1]!r}) follows {x[i]!r}"
    dy = np.diff(y)
    if not ((dy > 0).all() or (dy < 0).all()):
        return "y must be strictly monotonic (all increasing or all decreasing) so the table can be inverted"
    return None


def load_calibration_table(path: Path | str) -> CalibrationTable:
    """Read a calibration table CSV (format in the module docstring).

    Raises InvalidInput naming the file and line for: a missing/unreadable file, a missing or malformed
    header, a row without exactly two values, a bad number, NaN/inf, x not strictly increasing, y not
    strictly monotonic, fewer than two points.
    """
    p = Path(path)
    text = read_table_text(p, "calibration table")

    header: list[str] | None = None
    xs: list[float] = []
    ys: list[float] = []
    lines: list[int] = []
    for row in parse_header_table(text).lines:
        lineno, cells, line = row.line, list(row.cells), row.text
        where = f"calibration table {p}, line {lineno}"
        if len(cells) != 2:
            raise InvalidInput(f"{where}: expected 2 comma-separated columns, found {len(cells)}: {line!r}")
        if header is None:
            if any(_is_number(c) for c in cells) or not all(cells):
                raise InvalidInput(
                    f"{where}: expected a header row naming the two columns (e.g. 'real_deg,input_deg') "
                    f"before the numbers, found {line!r}"
                )
            header = cells
            continue
        try:
            xv, yv = float(cells[0]), float(cells[1])
        except ValueError:
            raise InvalidInput(f"{where}: not a number: {line!r}") from None
        if not (math.isfinite(xv) and math.isfinite(yv)):
            raise InvalidInput(f"{where}: values must be finite numbers, found {line!r}")
        if xs:
            if xv <= xs[-1]:
                raise InvalidInput(
                    f"{where}: {header[0]} must be strictly increasing, but {xv!r} follows {xs[-1]!r} "
                    f"(line {lines[-1]})"
                )
            turns = len(ys) >= 2 and (yv - ys[-1]) * (ys[-1] - ys[-2]) < 0
            if yv == ys[-1] or turns:
                raise InvalidInput(
                    f"{where}: {header[1]} must be strictly monotonic (the table is inverted), but it "
                    f"turns or repeats at {yv!r} after {ys[-1]!r}"
                )
        xs.append(xv)
        ys.append(yv)
        lines.append(lineno)
    if header is None:
        raise InvalidInput(f"calibration table {p}: no header row and no data (only comments or blank lines)")
    if len(xs) < 2:
        raise InvalidInput(f"calibration table {p}: needs at least 2 data rows, found {len(xs)}")
    return CalibrationTable(np.array(xs), np.array(ys), header[0], header[1], source=str(p))


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def write_calibration_table(path: Path | str, table: CalibrationTable, comment: str) -> Path:
    """Write `table` as a CSV that `load_calibration_table` reads back exactly (values written with repr).

    `comment` becomes '#' lines at the top (one per line of text). Returns the path written.
    """
    p = Path(path)
    comment_lines = [f"# {line}".rstrip() for line in comment.splitlines()] if comment else []
    rows = [f"{table.x_name},{table.y_name}"]
    rows += [f"{float(xv)!r},{float(yv)!r}" for xv, yv in zip(table.x, table.y, strict=True)]
    p.write_text("\n".join([*comment_lines, *rows]) + "\n", encoding="utf-8")
    return p


def _unique_mean(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Sort by x and average y over repeated x (repeated observations of one point)."""
    xu, inverse = np.unique(x, return_inverse=True)
    sums = np.bincount(inverse, weights=y)
    counts = np.bincount(inverse)
    return xu, sums / counts


def build_table_from_observations(
    input_deg: npt.ArrayLike,
    real_deg: npt.ArrayLike,
    output_deg: npt.ArrayLike,
    *,
    source: str = "observations",
) -> tuple[CalibrationTable, CalibrationTable]:
    """Build the two angle tables of thesis §2.5.1 from calibration observations.

    For each commanded angle α_input the operator noted the real angle α_real (marked on the joint) and the
    angle the computer showed α_output. Returns ``(command_table, angle_table)``:

    - command_table: ``real_deg -> input_deg`` (what to command to reach a real angle);
    - angle_table: ``output_deg -> real_deg`` (what the real angle is for a telemetry reading).

    Repeated observations of one commanded angle are averaged. Raises InvalidInput if the arrays differ in
    length, hold NaN, have fewer than two distinct points, or if a relation is not strictly monotonic (the
    robot's response must be invertible).
    """
    inp = np.asarray(input_deg, dtype=np.float64).ravel()
    real = np.asarray(real_deg, dtype=np.float64).ravel()
    out = np.asarray(output_deg, dtype=np.float64).ravel()
    if not (inp.shape == real.shape == out.shape):
        raise InvalidInput(
            f"{source}: input_deg, real_deg and output_deg must have the same number of observations, "
            f"got {inp.size}, {real.size} and {out.size}"
        )
    if not (np.isfinite(inp).all() and np.isfinite(real).all() and np.isfinite(out).all()):
        raise InvalidInput(f"{source}: observations contain NaN or infinite values")
    # Repeated commands of one input angle are averaged first (the commanded angle is the controlled one).
    inp_u, real_u = _unique_mean(inp, real)
    _, out_u = _unique_mean(inp, out)
    command = _table_from_pairs(real_u, inp_u, "real_deg", "input_deg", f"command table from {source}")
    angle = _table_from_pairs(out_u, real_u, "output_deg", "real_deg", f"angle table from {source}")
    return command, angle


def build_torque_table_from_observations(
    real_nm: npt.ArrayLike, output_nm: npt.ArrayLike, *, source: str = "observations"
) -> CalibrationTable:
    """Build the torque table of thesis §2.5.2 (``output_nm -> real_nm``) from applied (known) torques and
    the torques the computer showed."""
    real = np.asarray(real_nm, dtype=np.float64).ravel()
    out = np.asarray(output_nm, dtype=np.float64).ravel()
    if real.shape != out.shape:
        raise InvalidInput(f"{source}: real_nm and output_nm must have the same number of observations")
    return _table_from_pairs(out, real, "output_nm", "real_nm", f"torque table from {source}")


def _table_from_pairs(
    x: FloatArray, y: FloatArray, x_name: str, y_name: str, source: str
) -> CalibrationTable:
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise InvalidInput(f"{source}: observations contain NaN or infinite values")
    xu, yu = _unique_mean(x, y)
    if xu.size < 2:
        raise InvalidInput(f"{source}: needs at least 2 distinct {x_name} observations, got {xu.size}")
    dy = np.diff(yu)
    if not ((dy > 0).all() or (dy < 0).all()):
        raise InvalidInput(
            f"{source}: {y_name} is not strictly monotonic in {x_name}, so the relation cannot be inverted "
            "(check the observations for a typo or a stuck joint)"
        )
    return CalibrationTable(xu, yu, x_name, y_name, source=source)
