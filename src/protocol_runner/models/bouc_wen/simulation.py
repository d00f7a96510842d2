"""Simulating the Eq 23 recursion over given angle samples (thesis §6.2.3)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .kernels import IDENTITY8, recursion_kernel, sensitivity_kernel
from .params import DEFAULT_SIMULATION_BOUND_NM, BoucWenParams, FloatArray


def as_angle(x_deg: npt.ArrayLike, name: str = "x_deg") -> FloatArray:
    x = np.ascontiguousarray(x_deg, dtype=np.float64)
    if x.ndim != 1:
        raise InvalidInput(f"{name} must be a 1-D array of angles in degrees, got shape {x.shape}")
    if x.size == 0:
        raise InvalidInput(f"{name} is empty")
    if not np.all(np.isfinite(x)):
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        raise InvalidInput(f"{name} contains a non-finite value at sample {bad}")
    return x


def _check_bound(bound_nm: float) -> float:
    b = float(bound_nm)
    if not (b > 0.0 and math.isfinite(b)):
        raise InvalidInput(f"bound_nm must be a positive finite torque, got {bound_nm}")
    return b


def _check_z0(z0: float) -> float:
    z0f = float(z0)
    if not math.isfinite(z0f):
        raise InvalidInput(f"z0 must be a finite torque, got {z0}")
    return z0f


def simulate(
    x_deg: npt.ArrayLike,
    params: BoucWenParams,
    z0: float = 0.0,
    *,
    bound_nm: float = DEFAULT_SIMULATION_BOUND_NM,
) -> FloatArray:
    """Torque (N*m) predicted by the Eq 23 recursion over the angle samples ``x_deg`` (degrees).

    ``z[0] = z0`` and the output has the length of ``x_deg``.  If the recursion diverges (|z| exceeds
    ``bound_nm`` or stops being finite, which unstable parameter sets do) the remaining samples are NaN;
    ``np.isnan(z[-1])`` is the divergence flag.
    """
    x, z0f = as_angle(x_deg), _check_z0(z0)
    z = np.empty_like(x)
    recursion_kernel(
        x,
        np.array([0, x.size], dtype=np.int64),
        np.array([z0f]),
        params.A,
        params.n,
        np.array(params.beta),
        _check_bound(bound_nm),
        False,
        z,
    )
    return z


def simulate_sensitivity(
    x_deg: npt.ArrayLike,
    params: BoucWenParams,
    z0: float = 0.0,
    *,
    bound_nm: float = DEFAULT_SIMULATION_BOUND_NM,
) -> tuple[FloatArray, FloatArray]:
    """Eq 23 torque and its analytic Jacobian ``dz/dtheta`` (shape ``(len(x), 8)``) in one pass.

    Columns follow :data:`PARAM_NAMES` (A, n, beta1..beta6); ``z0`` is held fixed so row 0 is zero.
    Diverged samples are NaN in both outputs, as in :func:`simulate`.
    """
    x, z0f = as_angle(x_deg), _check_z0(z0)
    z = np.empty_like(x)
    dz = np.empty((x.size, 8))
    sensitivity_kernel(
        x,
        np.array([0, x.size], dtype=np.int64),
        np.array([z0f]),
        params.A,
        params.n,
        np.array(params.beta),
        _check_bound(bound_nm),
        False,
        z,
        dz,
        IDENTITY8,
    )
    return z, dz
