"""Trajectories of the protocol (thesis Appendix A and §3.1.1): pure functions of time, and trajectory files.

The sinusoid's period follows from a range and a peak speed (Eq 25), so the periods of Table 6 (8.17,
16.34, 3.14, 5.65, 6.91, 13.82 s) are never typed in. Every sample sent must satisfy the rig's envelope,
so the calibration step (Appendix A "Calibration") is a raised-cosine move, never a jump: a `ramp_s` too
short for the rate or acceleration limit (0 included) is refused at plan time. The time-constant fit
models the response to the commanded move, so the ramp does not bias tau (steps/calibration_check.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import InvalidInput
from ..tables import number_columns, parse_header_table, read_table_text

FloatArray = npt.NDArray[np.float64]


def sinusoid_period_s(amplitude_deg: float, max_speed_deg_s: float) -> float:
    """Period of the Eq 24 sinusoid whose maximum speed (Eq 25: amplitude * 2*pi/p) is `max_speed_deg_s`."""
    if amplitude_deg <= 0 or max_speed_deg_s <= 0:
        raise ValueError("amplitude and maximum speed must be positive")
    return 2.0 * math.pi * amplitude_deg / max_speed_deg_s


def sinusoid_deg(time_s: FloatArray, mean_deg: float, amplitude_deg: float, period_s: float) -> FloatArray:
    """Eq 24: mean + amplitude * sin(2*pi*t/p)."""
    return mean_deg + amplitude_deg * np.sin(2.0 * np.pi * np.asarray(time_s, dtype=np.float64) / period_s)


def identification_deg(
    time_s: FloatArray,
    min_deg: float,
    max_deg: float,
    repetition_s: float,
    initial_period_s: float,
    final_period_s: float,
) -> FloatArray:
    """The Eq 4-7 identification motion, rebuilt so that its repeats join without jumps.

    Thesis (Figure 25): y = min + E(tau) cos^2(phi(tau)), tau = t mod t_rep, with the envelope
    E(tau) = exp(ln(max - min) tau / t_rep) (Eq 4), the carrier period Period(tau) = t_final tau/t_rep +
    t_initial (t_rep - tau)/t_rep (Eq 5) and phi = pi tau / Period(tau).  Played as printed it ends each
    repeat near max and starts the next at min + 1 (a jump of about 108 deg), and ``pi tau / Period(tau)``
    turns faster than its period says (its rate is ``pi t_initial / Period^2``, a 0.5 s period at the end
    for 8 -> 2 s: peaks of about 670 deg/s).  Here:

    * Eq 4's time fraction ``tau / t_rep`` is replaced by ``s = (1 - cos(pi tau / t_rep)) / 2``: the envelope
      still grows exponentially from 1 to ``max - min`` but starts and ends with zero slope;
    * the carrier (Eq 6-7, cos^2) turns at the instantaneous period of Eq 5: ``phi`` is the integral of
      ``pi / Period``, scaled (by at most half a cycle over a repeat) so that a repeat holds a whole number
      of cycles - it then starts and ends at a crest (cos^2 = 1, zero slope), at min + 1 and at max;
    * every second repeat is the previous one played backwards (``tau -> t_rep - tau``): each repeat starts
      where the last ended, at rest, with the same acceleration - no jump, no blend needed.

    Peak speed is about ``pi (max - min) / t_final`` and peak acceleration ``2 pi^2 (max - min) / t_final^2``:
    choose ``t_final >= pi (max - min) / max_rate`` (110 deg at 120 deg/s: 2.9 s, the knee protocol uses
    3.2 s); the plan-time stream check refuses a motion outside the joint's limits.
    """
    t = np.asarray(time_s, dtype=np.float64)
    k = np.floor(t / repetition_s)
    tau = t - k * repetition_s
    tau = np.where(np.mod(k, 2.0) == 1.0, repetition_s - tau, tau)  # odd repeats run backwards
    s = 0.5 * (1.0 - np.cos(np.pi * tau / repetition_s))
    envelope = np.exp(math.log(max_deg - min_deg) * s)
    period = final_period_s * tau / repetition_s + initial_period_s * (repetition_s - tau) / repetition_s
    slope = (final_period_s - initial_period_s) / repetition_s
    if abs(slope) < 1e-12 * initial_period_s:
        cycles = tau / initial_period_s
        total = repetition_s / initial_period_s
    else:
        cycles = np.log(period / initial_period_s) / slope
        total = math.log(final_period_s / initial_period_s) / slope
    whole = max(1, round(total))
    phase = np.pi * cycles * (whole / total)
    return min_deg + envelope * np.cos(phase) ** 2


def calibration_step_deg(
    time_s: FloatArray, from_deg: float, step_deg: float, settle_s: float, ramp_s: float
) -> FloatArray:
    """Hold `from_deg` for `settle_s`, then move by `step_deg` over `ramp_s`, then hold.

    The move is a raised-cosine ramp (peak speed pi/2 * step/ramp, peak acceleration pi^2/2 * step/ramp^2)
    so the step stays inside the rig's rate and acceleration envelope; `ramp_s = 0` is a true step, which
    the plan-time stream check refuses.
    """
    t = np.asarray(time_s, dtype=np.float64)
    if ramp_s <= 0:
        frac = (t >= settle_s).astype(np.float64)
    else:
        x = np.clip((t - settle_s) / ramp_s, 0.0, 1.0)
        frac = 0.5 - 0.5 * np.cos(np.pi * x)
    return from_deg + step_deg * frac


def calibration_step_peak_speed_deg_s(step_deg: float, ramp_s: float) -> float:
    """Peak speed of the raised-cosine move: d/dt [step (1 - cos(pi t/ramp)) / 2] at t = ramp/2."""
    return math.inf if ramp_s <= 0 else math.pi / 2 * abs(step_deg) / ramp_s


def calibration_step_peak_accel_deg_s2(step_deg: float, ramp_s: float) -> float:
    """Peak acceleration of the raised-cosine move (at its start and end): pi^2/2 * step / ramp^2."""
    return math.inf if ramp_s <= 0 else math.pi**2 / 2 * abs(step_deg) / ramp_s**2


def sinusoid_peak_accel_deg_s2(amplitude_deg: float, max_speed_deg_s: float) -> float:
    """Peak acceleration of the Eq 24 sinusoid: amplitude * (2*pi/p)^2 = max_speed^2 / amplitude (Eq 25)."""
    return max_speed_deg_s**2 / amplitude_deg


def triangle_period_s(range_deg: float, speed_deg_s: float, corner_accel_deg_s2: float) -> float:
    """One cycle (low -> high -> low) of `triangle_deg`: two constant-speed legs of range - speed^2/accel
    and two corners of 2*speed/accel each, i.e. 2*range/speed + 2*speed/accel."""
    return 2.0 * range_deg / speed_deg_s + 2.0 * speed_deg_s / corner_accel_deg_s2


def triangle_deg(
    time_s: FloatArray, low_deg: float, high_deg: float, speed_deg_s: float, corner_accel_deg_s2: float
) -> FloatArray:
    """Triangle wave between `low_deg` and `high_deg` at constant speed, with acceleration-limited corners.

    Starts at rest at `low_deg`. Each corner is a parabola of constant acceleration `corner_accel_deg_s2`
    (a) whose apex is an end of the range: speed goes from +v to -v in 2v/a, and the constant-speed leg
    stops v^2/(2a) short of each end. So the extremes are exactly the range's ends, the peak speed is
    exactly v and the peak acceleration exactly a. Needs range >= v^2/a (else there is no constant-speed
    leg at all; `ValueError`)."""
    span = high_deg - low_deg
    v, a = speed_deg_s, corner_accel_deg_s2
    if span <= 0 or v <= 0 or a <= 0:
        raise ValueError("range, speed and corner acceleration must be positive")
    if span < v * v / a * (1.0 - 1e-12):
        raise ValueError(f"a {span:g} deg range is too short to reach {v:g} deg/s with {a:g} deg/s² corners")
    corner_s = v / a  # half a corner
    half_s = span / v + v / a  # low apex -> high apex
    t = np.asarray(time_s, dtype=np.float64)
    k = np.floor(t / half_s)
    u = t - k * half_s
    up = np.where(
        u < corner_s,
        0.5 * a * u * u,
        np.where(
            u > half_s - corner_s,
            span - 0.5 * a * (half_s - u) ** 2,
            0.5 * v * corner_s + v * (u - corner_s),
        ),
    )
    rising = np.mod(k, 2.0) == 0.0
    result: FloatArray = low_deg + np.where(rising, up, span - up)
    return result


def hold_deg(time_s: FloatArray, angle_deg: float) -> FloatArray:
    """`angle_deg` at every time."""
    return np.full(np.shape(time_s), float(angle_deg), dtype=np.float64)


@dataclass(frozen=True)
class TrajectoryFile:
    """An angle-vs-time trajectory read from a file."""

    path: Path
    time_s: FloatArray
    angle_deg: FloatArray
    header: str  # the comment lines: what the trajectory is and where it comes from
    column: str = "angle_deg"  # the angle column (or .mat variable) read

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    def at(self, time_s: FloatArray) -> FloatArray:
        """Linear interpolation at the given times (held at the ends)."""
        return np.interp(time_s, self.time_s - self.time_s[0], self.angle_deg)


_TIME_NAMES = ("time_s", "t", "time")
_ANGLE_NAMES = ("angle_deg", "angle", "theta_deg")


def _angle_names(joint: str | None) -> tuple[str, ...]:
    """The angle column for `joint`: the joint's name (or `<joint>_deg`), else a single joint's
    `angle_deg` (and the older spellings)."""
    return ((joint, f"{joint}_deg") if joint else ()) + _ANGLE_NAMES


def load_trajectory_file(path: Path, joint: str | None = None) -> TrajectoryFile:
    """Read a trajectory file.

    CSV: any number of comment lines starting with '#' (the header says what the trajectory is and where
    it comes from), then a row of column names containing `time_s` and an angle column - the joint's name
    (one column per joint: `knee_flexion,ankle_flexion`, or `knee_flexion_deg`) or, for a single joint,
    `angle_deg` - then numbers. MATLAB .mat: variables with the same names (vectors of equal length).
    Time must start at 0 or later and increase strictly. Errors name the file and line.
    """
    if not path.exists():
        raise InvalidInput(f"{path}: trajectory file not found")
    if path.is_dir():
        raise InvalidInput(f"{path}: is a directory, expected a trajectory file (.csv or .mat)")
    suffix = path.suffix.lower()
    if suffix == ".mat":
        time_s, angle_deg, header, column = _load_mat(path, _angle_names(joint))
    elif suffix in (".csv", ".txt"):
        time_s, angle_deg, header, column = _load_csv(path, _angle_names(joint))
    else:
        raise InvalidInput(f"{path}: unsupported trajectory file type {suffix!r} (use .csv or .mat)")
    if time_s.size < 2:
        raise InvalidInput(f"{path}: a trajectory needs at least two samples")
    if not (np.all(np.isfinite(time_s)) and np.all(np.isfinite(angle_deg))):
        raise InvalidInput(f"{path}: trajectory contains non-finite values")
    bad = np.flatnonzero(np.diff(time_s) <= 0)
    if bad.size:
        raise InvalidInput(f"{path}: time must increase strictly (sample {int(bad[0]) + 2} does not)")
    return TrajectoryFile(path=path, time_s=time_s, angle_deg=angle_deg, header=header, column=column)


_Columns = tuple[FloatArray, FloatArray, str, str]

_PARSED_CSV: dict[tuple[str, tuple[str, ...]], _Columns] = {}
"""Trajectory texts already parsed (text and angle names -> columns): a run reads each file several times
(the protocol and the session's copy of it are checked, every trial samples its file). Keyed by the whole
text, so a changed file is parsed anew; only files that parsed without error are kept; arrays read-only."""

_PARSED_CSV_MAX = 16


def _load_csv(path: Path, angle_names: tuple[str, ...]) -> _Columns:
    text = read_table_text(path, "trajectory file")
    key = (text, angle_names)
    parsed = _PARSED_CSV.get(key)
    if parsed is None:
        parsed = _parse_csv(path, text, angle_names)
        for array in parsed[:2]:
            array.flags.writeable = False
        if len(_PARSED_CSV) >= _PARSED_CSV_MAX:
            del _PARSED_CSV[next(iter(_PARSED_CSV))]  # the oldest
        _PARSED_CSV[key] = parsed
    return parsed


def _parse_csv(path: Path, text: str, angle_names: tuple[str, ...]) -> _Columns:
    table = parse_header_table(text)
    if table.header is None:
        raise InvalidInput(f"{path}: no column row and no data")
    columns = [c.lower() for c in table.header.cells]
    time_col = next((columns.index(n) for n in _TIME_NAMES if n in columns), -1)
    angle_col = next((columns.index(n.lower()) for n in angle_names if n.lower() in columns), -1)
    if time_col < 0 or angle_col < 0:
        wanted = f"`{angle_names[0]}` or `angle_deg`" if angle_names[0] != _ANGLE_NAMES[0] else "`angle_deg`"
        raise InvalidInput(
            f"{path}:{table.header.line}: the column row must name `time_s` and {wanted} "
            f"(found: {table.header.text})"
        )
    names = f"{table.header.cells[time_col]}, {table.header.cells[angle_col]}"
    times, angles = number_columns(
        table,
        (time_col, angle_col),
        lambda row: f"{path}:{row.line}: expected numbers in columns {names}: {row.text!r}",
    )
    return (
        np.asarray(times, dtype=np.float64),
        np.asarray(angles, dtype=np.float64),
        "\n".join(table.comments),
        table.header.cells[angle_col],
    )


MAX_MAT_ELEMENTS = 20_000_000
"""Most elements a trajectory .mat may hold in all (its variables' declared sizes, read before loading): a
few megabytes of compressed zeros can declare gigabytes."""


def _load_mat(path: Path, angle_names: tuple[str, ...]) -> tuple[FloatArray, FloatArray, str, str]:
    from scipy.io import loadmat, whosmat

    try:
        declared = sum(math.prod(shape) for _, shape, _ in whosmat(str(path)))
    except Exception as exc:  # scipy raises several types for a broken file
        raise InvalidInput(f"{path}: not a readable MATLAB .mat file ({exc})") from None
    if declared > MAX_MAT_ELEMENTS:
        raise InvalidInput(
            f"{path}: its variables hold {declared:,} elements, more than the {MAX_MAT_ELEMENTS:,} a "
            "trajectory file may have"
        )
    try:
        contents = loadmat(str(path), squeeze_me=True)
    except Exception as exc:  # scipy raises several types for a broken file
        raise InvalidInput(f"{path}: not a readable MATLAB .mat file ({exc})") from None
    time_name = next((n for n in _TIME_NAMES if n in contents), None)
    angle_name = next((n for n in angle_names if n in contents), None)
    if time_name is None or angle_name is None:
        names = ", ".join(sorted(k for k in contents if not k.startswith("__")))
        raise InvalidInput(
            f"{path}: needs variables `time_s` and `{angle_names[0]}` (found: {names or 'none'})"
        )
    time_s = np.asarray(contents[time_name], dtype=np.float64).ravel()
    angle_deg = np.asarray(contents[angle_name], dtype=np.float64).ravel()
    if time_s.shape != angle_deg.shape:
        raise InvalidInput(f"{path}: `{time_name}` and `{angle_name}` have different lengths")
    header = str(contents.get("description", contents.get("__header__", b"")))
    return time_s, angle_deg, header, angle_name
