"""A plan trajectory sampled at the output rate: the samples a trial or calibration check commands.

One function for the run (steps/trial.py, steps/calibration_check.py) and the plan-time envelope check
(protocol/stream_check.py), so both see exactly the same samples.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from .plan_trajectory import Trajectory
from .trajectories import (
    calibration_step_deg,
    identification_deg,
    load_trajectory_file,
    sinusoid_deg,
)

FloatArray = npt.NDArray[np.float64]


def sample_trajectory(trajectory: Trajectory, rate_hz: float, base_dir: Path) -> FloatArray:
    """Real joint angles, one per output tick (t = 0, 1/rate, ... < duration); human files are read from
    `base_dir`."""
    t = np.arange(0.0, trajectory.duration_s, 1.0 / rate_hz)
    p = dict(trajectory.params)
    if trajectory.profile == "sinusoid":
        assert (
            trajectory.mean_deg is not None and trajectory.amplitude_deg is not None and trajectory.period_s
        )
        return sinusoid_deg(t, trajectory.mean_deg, trajectory.amplitude_deg, trajectory.period_s)
    if trajectory.profile == "human":
        assert trajectory.source is not None
        return load_trajectory_file(base_dir / trajectory.source).at(t)
    if trajectory.profile == "identification":
        return identification_deg(
            t,
            float(p["min_deg"]),
            float(p["max_deg"]),
            float(p["repetition_s"]),
            float(p["initial_period_s"]),
            float(p["final_period_s"]),
        )
    if trajectory.profile == "step":
        return calibration_step_deg(
            t, float(p["from_deg"]), float(p["step_deg"]), float(p["settle_s"]), float(p["ramp_s"])
        )
    raise ValueError(f"unknown trajectory profile {trajectory.profile!r}")
