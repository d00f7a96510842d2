"""An external torque-angle dataset to compare with (the EMU data of thesis §5.6), read from CSV or .mat.

The protocol names such files (`validate` checks they read); the report draws them. Format in
docs/report.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InvalidInput, short
from ..tables import number_columns, parse_header_table, read_table_text

FloatArray = np.ndarray


@dataclass(frozen=True)
class ReferenceDataset:
    """An external torque-angle dataset to compare with (the EMU data of §5.6)."""

    source: str
    title: str
    angle_deg: FloatArray
    torque_nm: FloatArray


def load_reference_dataset(path: Path, title: str | None = None) -> ReferenceDataset:
    """Read an external torque-angle dataset (EMU data, thesis §5.6) from CSV or MATLAB .mat.

    CSV: optional `#` comment lines, a header row, numeric rows; the angle column is the first whose
    header contains "angle" and the torque column the first containing "torque" (degrees and N*m).
    .mat: the first variables whose names start with "angle" and "torque" (case-insensitive), any shape,
    flattened. Raises `InvalidInput` naming the file on any defect.
    """
    path = Path(path)
    if not path.is_file():
        raise InvalidInput(f"Reference dataset {path} does not exist.")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        angle, torque = _read_reference_csv(path)
    elif suffix == ".mat":
        angle, torque = _read_reference_mat(path)
    else:
        raise InvalidInput(f"Reference dataset {path}: unsupported format {suffix!r} (use .csv or .mat).")
    if angle.size != torque.size or angle.size < 2:
        raise InvalidInput(
            f"Reference dataset {path}: angle and torque columns must have the same length >= 2 "
            f"(got {angle.size} and {torque.size})."
        )
    if not (np.all(np.isfinite(angle)) and np.all(np.isfinite(torque))):
        raise InvalidInput(f"Reference dataset {path}: angle and torque must be finite numbers.")
    return ReferenceDataset(
        source=str(path), title=title or path.stem, angle_deg=_read_only(angle), torque_nm=_read_only(torque)
    )


def _read_only(arr: np.ndarray) -> np.ndarray:
    out = np.asarray(arr).view()
    out.flags.writeable = False
    return out


def _read_reference_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    text = read_table_text(path, "Reference dataset")
    table = parse_header_table(text)
    if table.header is None:
        raise InvalidInput(f"Reference dataset {path} has no header row.")
    header_line = table.header.line
    header = [h.lower() for h in table.header.cells]
    angle_col = next((i for i, h in enumerate(header) if "angle" in h), None)
    torque_col = next((i for i, h in enumerate(header) if "torque" in h), None)
    if angle_col is None or torque_col is None:
        raise InvalidInput(
            f"Reference dataset {path}, line {header_line}: the header must name an angle column and a "
            f"torque column (got {header})."
        )
    angle, torque = number_columns(
        table,
        (angle_col, torque_col),
        lambda row: f"Reference dataset {path}, line {row.line}: not a number row ({row.text!r}).",
    )
    return np.asarray(angle), np.asarray(torque)


def _read_reference_mat(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from scipy.io import loadmat  # imported lazily: only the EMU comparison needs it
    from scipy.io.matlab import MatReadError  # an empty or truncated file

    try:
        content = loadmat(str(path))
    except (OSError, ValueError, NotImplementedError, TypeError, MatReadError) as exc:
        raise InvalidInput(
            f"Reference dataset {path} is not a readable MATLAB .mat file ({short(exc)})."
        ) from exc
    names = [k for k in content if not k.startswith("__")]
    angle_name = next((k for k in names if k.lower().startswith("angle")), None)
    torque_name = next((k for k in names if k.lower().startswith("torque")), None)
    if angle_name is None or torque_name is None:
        raise InvalidInput(
            f"Reference dataset {path}: needs variables named angle* and torque* (found {sorted(names)})."
        )
    try:
        angle = np.asarray(content[angle_name], dtype=float).reshape(-1)
        torque = np.asarray(content[torque_name], dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidInput(f"Reference dataset {path}: {angle_name}/{torque_name} are not numeric.") from exc
    return angle, torque
