"""The two integration schemes of the Bouc-Wen state, selected by name.

* ``"refined"`` (the default everywhere): Eq 20-22 integrated along the piecewise-linear angle with
  bounded, state-dependent substeps (:mod:`.integrator`); the torque does not depend on the sampling rate.
* ``"eq23"``: the thesis's literal recursion, one explicit Euler step per sample (Eq 23, :mod:`.kernels`);
  its torque changes with the sampling rate.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .integrator import DEFAULT_MAX_STEP_DEG, heun_kernel, heun_sensitivity_kernel
from .kernels import recursion_kernel, sensitivity_kernel
from .params import FloatArray

IntArray = npt.NDArray[np.int64]

REFINED = "refined"
EQ23 = "eq23"
SCHEMES = (REFINED, EQ23)


def check_scheme(scheme: str, max_step_deg: float | None) -> float:
    """Validate a scheme name and substep length; the substep length to use (deg)."""
    if scheme not in SCHEMES:
        raise InvalidInput(f"scheme must be one of {', '.join(SCHEMES)}, got {scheme!r}")
    step = DEFAULT_MAX_STEP_DEG if max_step_deg is None else float(max_step_deg)
    if not (step > 0.0 and math.isfinite(step)):
        raise InvalidInput(f"max_step_deg must be a positive finite angle, got {max_step_deg}")
    return step


def run_scheme(
    scheme: str,
    x: FloatArray,
    seg: IntArray,
    z0: FloatArray,
    A: float,
    n: float,
    beta: npt.ArrayLike,
    bound: float,
    freeze: bool,
    z: FloatArray,
    max_step_deg: float | None = None,
) -> int:
    """Torque into ``z``; index of the first diverged sample or -1 (see the kernels)."""
    step = check_scheme(scheme, max_step_deg)
    if scheme == EQ23:
        return int(recursion_kernel(x, seg, z0, A, n, np.asarray(beta), bound, freeze, z))
    return int(heun_kernel(x, seg, z0, A, n, np.asarray(beta), bound, freeze, step, z))


def run_scheme_sensitivity(
    scheme: str,
    x: FloatArray,
    seg: IntArray,
    z0: FloatArray,
    A: float,
    n: float,
    beta: npt.ArrayLike,
    bound: float,
    freeze: bool,
    z: FloatArray,
    dz: FloatArray,
    T: FloatArray,
    max_step_deg: float | None = None,
    rows: IntArray | None = None,
) -> int:
    """Torque into ``z`` and ``dz/dtheta @ T`` into ``dz``; index of the first diverged sample or -1.

    rows: the samples whose derivatives are wanted (increasing; ``dz`` has one row per entry), every
    sample when None."""
    step = check_scheme(scheme, max_step_deg)
    if scheme == EQ23:
        if rows is None:
            return int(sensitivity_kernel(x, seg, z0, A, n, np.asarray(beta), bound, freeze, z, dz, T))
        full = np.empty((x.size, 8))
        bad = int(sensitivity_kernel(x, seg, z0, A, n, np.asarray(beta), bound, freeze, z, full, T))
        dz[:] = full[rows]
        return bad
    every = np.arange(x.size, dtype=np.int64) if rows is None else rows
    return int(
        heun_sensitivity_kernel(x, seg, z0, A, n, np.asarray(beta), bound, freeze, step, z, dz, T, every)
    )
