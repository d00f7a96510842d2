"""A plan trajectory sampled at the output rate: the samples a trial or calibration check commands.

One function for the run (steps/trial.py, steps/calibration_check.py) and the plan-time envelope check
(protocol/stream_check.py), so all of them see exactly the same samples:
one per output tick, t = 0, 1/rate, ... < duration_s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..errors import InvalidInput
from .trajectory_record import Trajectory
from .trajectory_specs import trajectory_kind

FloatArray = npt.NDArray[np.float64]


MAX_COMMAND_SAMPLES = 5_000_000
"""Longest commanded trajectory (samples at the output rate): about 14 h at 100 Hz."""


def samples_problem(trajectory: Trajectory, rate_hz: float) -> str:
    """Why `trajectory` is too long to sample at `rate_hz` ("" if it is not): more than MAX_COMMAND_SAMPLES."""
    n_samples = trajectory.duration_s * rate_hz
    if n_samples <= MAX_COMMAND_SAMPLES:
        return ""
    return (
        f"it lasts {trajectory.duration_s:.0f} s: {n_samples:,.0f} samples at {rate_hz:g} Hz, more than the "
        f"{MAX_COMMAND_SAMPLES:,} a trajectory may have"
    )


def sample_trajectory(trajectory: Trajectory, rate_hz: float, base_dir: Path) -> FloatArray:
    """Real joint angles, one per output tick (t = 0, 1/rate, ... < duration_s), as its kind samples them;
    files are read from `base_dir`. `InvalidInput` for more than MAX_COMMAND_SAMPLES (the protocol's checks
    refuse it first, naming its field)."""
    too_long = samples_problem(trajectory, rate_hz)
    if too_long:
        raise InvalidInput(f"trajectory {trajectory.name or trajectory.profile!r}: {too_long}")
    time_s = np.arange(0.0, trajectory.duration_s, 1.0 / rate_hz)
    return trajectory_kind(trajectory.profile).sample(trajectory, time_s, base_dir)
