"""The two integration schemes of the Bouc-Wen state, selected by name (compiled in :mod:`.kernels`).

* ``"refined"`` (the default everywhere): the angle piecewise linear between samples, and Eq 20 with the
  shape function of Eq 22, ``dz/dx = A - |z|^n Psi(sgn dx, sgn x, sgn z)``, integrated along it by Heun's
  method on ``m = ceil(|dx| max(1 / h, |dF/dz| / (STIFF_STEP h / DEFAULT_MAX_STEP_DEG)))`` substeps per
  interval (``h = max_step_deg``, at most ``MAX_SUBSTEPS``; shorter where the loop saturates, ``|dF/dz| =
  n |z|^(n-1) |Psi|``), each interval cut exactly where the angle crosses 0 (``sgn x`` switches Psi). The
  substeps depend on the angle path and the state, not the sampling rate: the torque does not either.
* ``"eq23"``: the thesis's literal recursion, one explicit Euler step per sample (Eq 23); its torque
  changes with the sampling rate.

The sensitivities ``dz/dtheta`` (theta = A, n, beta1..6) are exact derivatives of the discrete scheme, so
the optimiser's Jacobian matches its residuals. docs/analysis.md §9 ("Integration") gives the reasons.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .kernels import DEFAULT_MAX_STEP_DEG, IDENTITY8, NO_SENSITIVITY, kernel
from .params import BoucWenParams, FloatArray

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


class BoucWenShape(NamedTuple):
    """The shape parameters of Eq 20-22: ``A``, ``n`` and ``beta1..6`` (a float64 array of 6, as the
    compiled kernels take it)."""

    A: float
    n: float
    beta: FloatArray


class Integration(NamedTuple):
    """How the state is integrated: the scheme (``"refined"`` or ``"eq23"``), the |z| bound (N*m) past
    which a segment has diverged, whether a diverged segment is held at +-``bound`` (``freeze``, the
    fitter's finite penalty) or NaN, the longest substep of the refined scheme (deg; default when None),
    and whether to stop at the first divergence (``stop_at_divergence``: a check whose only use is whether
    it diverges; the torque and derivatives of a check that diverged are then incomplete, and must not be
    read)."""

    scheme: str
    bound: float
    freeze: bool = True
    max_step_deg: float | None = None
    stop_at_divergence: bool = False


class Sensitivity(NamedTuple):
    """Where the derivatives go: ``dz`` receives ``dz/dtheta @ T`` at the samples ``rows`` (increasing;
    one row of ``dz`` per entry), at every sample when ``rows`` is None."""

    dz: FloatArray
    T: FloatArray = IDENTITY8
    rows: IntArray | None = None


def run_scheme(
    x: FloatArray,
    seg: IntArray,
    z0: FloatArray,
    shape: BoucWenShape,
    integration: Integration,
    z: FloatArray,
    sensitivity: Sensitivity | None = None,
) -> int:
    """Torque into ``z`` over the segments ``x[seg[s]:seg[s+1]]``, each started at ``z0[s]``; with a
    ``sensitivity``, also its derivatives.  Returns the index of the first diverged sample or -1 (see
    :func:`.kernels._sweep`)."""
    scheme = integration.scheme
    step = check_scheme(scheme, integration.max_step_deg)
    shape_rec = (shape.A, shape.n, np.asarray(shape.beta, dtype=np.float64))
    limits = (integration.bound, integration.freeze, step, integration.stop_at_divergence)
    sens = NO_SENSITIVITY
    if sensitivity is not None:
        dz, T, rows = sensitivity
        sens = (dz, T, np.arange(x.size, dtype=np.int64) if rows is None else rows)
    return int(kernel(x, seg, z0, shape_rec, limits, z, sens, scheme == REFINED, sensitivity is not None))


def run_trial(
    x: FloatArray,
    params: BoucWenParams,
    z0: float,
    integration: Integration,
    dz: FloatArray | None = None,
) -> tuple[FloatArray, int]:
    """One trial from ``z0``: the torque at every sample of ``x`` and the first diverged index or -1; with
    ``dz`` (``len(x)`` x 8) also ``dz/dtheta`` into it."""
    z = np.empty_like(x)
    seg = np.array([0, x.size], dtype=np.int64)
    shape = BoucWenShape(params.A, params.n, np.array(params.beta))
    sensitivity = None if dz is None else Sensitivity(dz)
    bad = run_scheme(x, seg, np.array([z0]), shape, integration, z, sensitivity)
    return z, bad


def segment_starts(xs: list[FloatArray]) -> IntArray:
    """Where each of the trials ``xs`` starts once they are concatenated, and their total (one more entry
    than trials): the kernels' ``seg``."""
    seg = np.zeros(len(xs) + 1, dtype=np.int64)
    seg[1:] = np.cumsum([x.size for x in xs])
    return seg


def run_trials(
    xs: list[FloatArray], params: BoucWenParams, z0s: list[float], integration: Integration
) -> tuple[list[FloatArray], int]:
    """Several trials in one call, each from its own ``z0`` (no derivatives): each trial's torque (views
    of one array) and the first diverged index over all of them (in the joint samples) or -1. Each
    trial's torque is bit for bit :func:`run_trial`'s (the kernels integrate the segments one after the
    other, each from its own start)."""
    seg = segment_starts(xs)
    x = np.concatenate(xs) if xs else np.empty(0)
    z = np.empty_like(x)
    shape = BoucWenShape(params.A, params.n, np.array(params.beta))
    bad = run_scheme(x, seg, np.array(z0s, dtype=np.float64), shape, integration, z)
    return [z[seg[k] : seg[k + 1]] for k in range(len(xs))], bad
