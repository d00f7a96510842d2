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
    """The options of :func:`simulate` and :func:`simulate_trials`.

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


def simulate(
    x_deg: npt.ArrayLike, params: BoucWenParams, z0: float = 0.0, **options: Unpack[SimulateKeywords]
) -> FloatArray:
    """Torque (N*m) predicted by the generalised Bouc-Wen model over the angle samples ``x_deg`` (degrees).

    scheme: ``"refined"`` (default, the model :func:`fit` fits) integrates Eq 20-22 along the piecewise
        linear angle independently of the sampling rate; ``"eq23"`` is the thesis's literal recursion
        (Eq 23, one explicit Euler step per sample, ``sgn(0) = 0``); see :mod:`.schemes`.

    ``z[0] = z0`` and the output has the length of ``x_deg``.  If the recursion diverges (|z| exceeds
    ``bound_nm`` or stops being finite, which unstable parameter sets do) the remaining samples are NaN;
    ``np.isnan(z[-1])`` is the divergence flag.
    """
    z, _ = run_trial(as_angle(x_deg), params, _start(z0), _integration(options))
    return z


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


def refine_angle(x_deg: npt.ArrayLike, factor: int = 4) -> FloatArray:
    """The angle samples with ``factor - 1`` linearly interpolated samples between each pair; the
    original samples are at indices ``0, factor, 2 factor, ...``."""
    x = as_angle(x_deg)
    if factor < 1:
        raise InvalidInput(f"factor must be >= 1, got {factor}")
    t = np.arange((x.size - 1) * factor + 1) / factor
    return np.interp(t, np.arange(x.size), x)
