"""The Bouc-Wen fit of a configuration's centred loops (thesis §6.2), from plain arrays.

Used by the fit step and by `--reprocess`, so both give the same numbers.
"""

from __future__ import annotations

import numpy as np

from ..models.bouc_wen import BoucWenFit, cross_validate, fit_trials
from .centring import centre


def centred_loop(angle_deg: np.ndarray, torque_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A processed trial centred on (0, 0) (§6.2.3 note), undefined samples dropped."""
    keep = np.isfinite(torque_nm)
    loop = centre(angle_deg[keep], torque_nm[keep])
    return loop.angle_deg, loop.torque_nm


def fit_loops(
    segments: list[tuple[np.ndarray, np.ndarray]], *, starts: int, cross_validated: bool
) -> tuple[BoucWenFit, list[float]]:
    """The joint fit over a configuration's trials, and leave-one-trial-out RMSEs when asked and possible."""
    result = fit_trials(segments, starts=starts)
    cv: list[float] = []
    if cross_validated and len(segments) >= 2:
        # warm-started from the joint fit (the held-out error is measured on every sample of the trial)
        cv = cross_validate(segments, initial=result.params)
    return result, cv
