"""Input checks shared by the analysis functions, and the error they raise: an `AnalysisError` (an
`InvalidInput`, exit status 2) naming the quantity and the reason when the archived data and the protocol's
settings do not allow a step (a trial shorter than the filter's padding, a transition never reached, ...).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

FloatArray = npt.NDArray[np.float64]
#: Precision of stored measured and processed signals (7 significant digits, far below sensor resolution);
#: the Bouc-Wen fit runs on the processed loops in this precision, as stored (analysis/service.py).
SIGNAL = np.float32


class AnalysisError(InvalidInput):
    """The data or the processing settings do not allow the requested analysis step."""


def as_signal(
    name: str, values: npt.ArrayLike, *, min_length: int = 1, allow_nan: bool = False
) -> FloatArray:
    """`values` as a 1-D float64 array of at least `min_length` samples, finite unless `allow_nan`, or
    `AnalysisError` naming `name`."""
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise AnalysisError(f"{name}: expected numbers, got {type(values).__name__} ({exc})") from None
    if array.ndim != 1:
        raise AnalysisError(f"{name}: expected a 1-D array of samples, got shape {array.shape}")
    if array.shape[0] < min_length:
        raise AnalysisError(f"{name}: needs at least {min_length} samples, got {array.shape[0]}")
    if not allow_nan and not np.all(np.isfinite(array)):
        bad = int(np.flatnonzero(~np.isfinite(array))[0])
        raise AnalysisError(f"{name}: sample {bad} is not a finite number ({array[bad]})")
    return array


def same_length(**signals: FloatArray) -> int:
    """Return the common length of the named signals, or raise `AnalysisError` listing the lengths."""
    lengths = {name: int(s.shape[0]) for name, s in signals.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{name}={n}" for name, n in lengths.items())
        raise AnalysisError(f"signals must have the same number of samples: {detail}")
    return next(iter(lengths.values()))


def signal_pair(
    x_name: str, x: npt.ArrayLike, y_name: str, y: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Two signals of one recording (e.g. its angle and torque) checked as `as_signal` and of the same
    length, or `AnalysisError` naming them."""
    xs, ys = as_signal(x_name, x), as_signal(y_name, y)
    same_length(**{x_name: xs, y_name: ys})
    return xs, ys
