"""Simulating the Bouc-Wen torque over given angle samples (thesis §6.2.3): step-independent by default,
the literal Eq 23 recursion on request (``scheme="eq23"``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypedDict, Unpack

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .params import DEFAULT_SIMULATION_BOUND_NM, BoucWenParams, FloatArray
from .schemes import REFINED, Integration, check_scheme, run_trial, run_trials


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


class SimulateKeywords(TypedDict, total=False):
    """The options of :func:`simulate` and :func:`simulate_sensitivity`.

    bound_nm: |z| beyond which the state counts as diverged (default ``DEFAULT_SIMULATION_BOUND_NM``).
    scheme: ``"refined"`` (default) or ``"eq23"``, see :func:`simulate`.
    max_step_deg: longest substep of the refined integration (default
        :data:`.kernels.DEFAULT_MAX_STEP_DEG`).
    """

    bound_nm: float
    scheme: str
    max_step_deg: float | None


def _start(z0: float) -> float:
    """A starting torque as a finite float (InvalidInput otherwise)."""
    z0f = float(z0)
    if not math.isfinite(z0f):
        raise InvalidInput(f"z0 must be a finite torque, got {z0}")
    return z0f


def _integration(options: SimulateKeywords) -> Integration:
    """The options' integration, NaN from a divergence on."""
    scheme, step = options.get("scheme", REFINED), options.get("max_step_deg")
    check_scheme(scheme, step)
    bound_nm = options.get("bound_nm", DEFAULT_SIMULATION_BOUND_NM)
    bound = float(bound_nm)
    if not (bound > 0.0 and math.isfinite(bound)):
        raise InvalidInput(f"bound_nm must be a positive finite torque, got {bound_nm}")
    return Integration(scheme, bound, False, step)


def _run(
    x_deg: npt.ArrayLike, params: BoucWenParams, z0: float, options: SimulateKeywords, sensitivities: bool
) -> tuple[FloatArray, FloatArray | None]:
    """The torque of one trial from ``z0`` (divergence: NaN from there on) and, when asked, ``dz/dtheta``."""
    x = as_angle(x_deg)
    z0f = _start(z0)
    integration = _integration(options)
    dz = np.empty((x.size, 8)) if sensitivities else None
    z, _ = run_trial(x, params, z0f, integration, dz)
    return z, dz


def simulate(
    x_deg: npt.ArrayLike, params: BoucWenParams, z0: float = 0.0, **options: Unpack[SimulateKeywords]
) -> FloatArray:
    """Torque (N*m) predicted by the generalised Bouc-Wen model over the angle samples ``x_deg`` (degrees).

    scheme: ``"refined"`` (default) integrates Eq 20-22 along the angle taken as piecewise linear between
        samples, with substeps of at most ``max_step_deg`` (default 0.1 deg) and shorter where the loop
        saturates (:mod:`.schemes`): the result does not depend on the sampling rate, and it is the
        model :func:`fit` fits.  ``"eq23"`` is the thesis's literal recursion (Eq 23, one explicit Euler
        step per sample, ``sgn(0) = 0``), whose torque changes with the sampling rate.

    ``z[0] = z0`` and the output has the length of ``x_deg``.  If the recursion diverges (|z| exceeds
    ``bound_nm`` or stops being finite, which unstable parameter sets do) the remaining samples are NaN;
    ``np.isnan(z[-1])`` is the divergence flag.
    """
    return _run(x_deg, params, z0, options, False)[0]


def simulate_trials(
    xs_deg: Sequence[npt.ArrayLike],
    params: BoucWenParams,
    z0s: Sequence[float],
    **options: Unpack[SimulateKeywords],
) -> list[FloatArray]:
    """:func:`simulate` of several trials, each from its own ``z0``, in one call of the kernel: each torque
    bit for bit :func:`simulate`'s for that trial."""
    if len(xs_deg) != len(z0s):
        raise InvalidInput(f"{len(xs_deg)} trials but {len(z0s)} starting torques")
    xs = [as_angle(x, f"trial {k} angle") for k, x in enumerate(xs_deg)]
    starts = [_start(z0) for z0 in z0s]
    torques, _ = run_trials(xs, params, starts, _integration(options))
    return torques


def simulate_sensitivity(
    x_deg: npt.ArrayLike, params: BoucWenParams, z0: float = 0.0, **options: Unpack[SimulateKeywords]
) -> tuple[FloatArray, FloatArray]:
    """Torque (as :func:`simulate`) and its analytic Jacobian ``dz/dtheta`` (shape ``(len(x), 8)``) in one pass.

    Columns follow :data:`PARAM_NAMES` (A, n, beta1..beta6); ``z0`` is held fixed so row 0 is zero.
    Diverged samples are NaN in both outputs, as in :func:`simulate`.
    """
    z, dz = _run(x_deg, params, z0, options, True)
    assert dz is not None
    return z, dz


def refine_angle(x_deg: npt.ArrayLike, factor: int = 4) -> FloatArray:
    """The angle samples with ``factor - 1`` linearly interpolated samples between each pair; the
    original samples are at indices ``0, factor, 2 factor, ...``."""
    x = as_angle(x_deg)
    if factor < 1:
        raise InvalidInput(f"factor must be >= 1, got {factor}")
    t = np.arange((x.size - 1) * factor + 1) / factor
    return np.interp(t, np.arange(x.size), x)


def simulate_refined(
    x_deg: npt.ArrayLike,
    params: BoucWenParams,
    z0: float = 0.0,
    *,
    factor: int = 4,
    **options: Unpack[SimulateKeywords],
) -> FloatArray:
    """:func:`simulate` with the same parameters and ``factor``-times finer integration: the angle samples
    interpolated ``factor`` times finer, every substep ``factor`` times shorter, and the torque read back at
    the original samples (the check that a fit describes the joint, not the integrator)."""
    fine = options.copy()
    fine["max_step_deg"] = check_scheme(options.get("scheme", REFINED), options.get("max_step_deg")) / factor
    return simulate(refine_angle(x_deg, factor), params, z0, **fine)[::factor]
