"""The Bouc-Wen torque with its analytic Jacobian, as the fitter's kernels compute it, for the tests of
those derivatives."""

from __future__ import annotations

from typing import Unpack

import numpy as np
import numpy.typing as npt

from protocol_runner.models.bouc_wen.params import BoucWenParams, FloatArray
from protocol_runner.models.bouc_wen.schemes import run_trial
from protocol_runner.models.bouc_wen.simulation import SimulateKeywords, _integration, _start, as_angle


def simulate_sensitivity(
    x_deg: npt.ArrayLike, params: BoucWenParams, z0: float = 0.0, **options: Unpack[SimulateKeywords]
) -> tuple[FloatArray, FloatArray]:
    """Torque (as `simulate`) and its Jacobian ``dz/dtheta`` (``len(x)`` x 8, columns A, n, beta1..6) in
    one pass; ``z0`` is held fixed so row 0 is zero; diverged samples are NaN in both."""
    x = as_angle(x_deg)
    z0f = _start(z0)
    dz = np.empty((x.size, 8))
    z, _ = run_trial(x, params, z0f, _integration(options), dz)
    return z, dz
