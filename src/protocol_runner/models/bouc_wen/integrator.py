"""Compiled step-independent integration of the Bouc-Wen state (Eq 20-22) and its sensitivities.

Eq 23 takes one explicit Euler step per sample, so its torque depends on the sampling rate.  Here the angle
is taken as piecewise linear between samples and the differential equation of Eq 20 with the shape
function of Eq 22, ``dz/dx = A - |z|^n Psi(sgn dx, sgn x, sgn z)``, is integrated along it with Heun's
second-order method (explicit trapezoidal rule) on substeps of the angle:

* each sample interval ``x_i -> x_{i+1}`` is cut into ``m`` equal substeps with
  ``m = ceil(|dx| max(1 / h, |dF/dz| / (STIFF_STEP h / DEFAULT_MAX_STEP_DEG)))``, ``h = max_step_deg`` (at most ``MAX_SUBSTEPS``): no substep
  longer than ``max_step_deg`` and, where the loop saturates (``|dF/dz| = n |z|^(n-1) |Psi|`` large),
  short enough to stay well inside the method's stability region;
* an interval on which the angle crosses 0 is cut there exactly (``sgn x`` switches Psi, and the torque's
  rate jumps by ``|z|^n`` times the change of Psi); within a piece ``sgn dx`` and ``sgn x`` are constant
  and ``sgn z`` is that of each stage's own torque (the rate is continuous across z = 0, where
  ``|z|^n = 0``);
* the substep count depends on the angle path and the state, not on the sampling rate: the same parameters
  give the same torque (to the scheme's accuracy) whether the angle is sampled at 200 Hz or 1 kHz.

The sensitivities ``d z / d theta`` (theta = A, n, beta1..6) are those of the discrete scheme (exact
derivatives of what is computed, so the optimiser's Jacobian matches its residuals).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernels import project_row, sgn

STIFF_STEP = 0.5  # substep * |dF/dz| at most this at the default substep (Heun is stable to 2 on the
# negative real axis); a shorter max_step_deg shortens this bound in proportion (one knob for fineness)
MAX_SUBSTEPS = 256  # per sample interval: bounded work for any parameter set
DEFAULT_MAX_STEP_DEG = 0.1  # longest substep of the angle (deg)


@njit(cache=True)
def _substeps(d, zi, A, n, beta, sx, max_step, stiff_step):  # pragma: no cover - compiled
    """Substep count of a piece, and the rate ``dz/dx`` at its start (one power of |z| for both)."""
    sd = sgn(d)
    sz = sgn(zi)
    psi = (
        beta[0] * sd * sz + beta[1] * sd * sx + beta[2] * sx * sz + beta[3] * sd + beta[4] * sz + beta[5] * sx
    )
    az = abs(zi)
    g = math.exp(n * math.log(az)) if az > 0.0 else 0.0
    stiff = n * g / az * abs(psi) if az > 0.0 else 0.0
    rate = max(1.0 / max_step, stiff / stiff_step)
    m = math.ceil(abs(d) * rate) if math.isfinite(rate) else MAX_SUBSTEPS
    return max(1, min(MAX_SUBSTEPS, m)), A - g * psi


@njit(cache=True)
def _rate(z, A, n, beta, sd, sx):  # pragma: no cover - compiled
    sz = sgn(z)
    psi = (
        beta[0] * sd * sz + beta[1] * sd * sx + beta[2] * sx * sz + beta[3] * sd + beta[4] * sz + beta[5] * sx
    )
    az = abs(z)
    g = math.exp(n * math.log(az)) if az > 0.0 else 0.0
    return A - g * psi


@njit(cache=True)
def _piece(xa, xb, zi, A, n, beta, bound, max_step):  # pragma: no cover - compiled
    """Heun substeps along the straight angle piece ``xa -> xb`` on which sgn x does not change."""
    d = xb - xa
    sd = sgn(d)
    sx = sgn(xa + 0.5 * d)
    m, k1 = _substeps(d, zi, A, n, beta, sx, max_step, max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG)
    h = d / m
    for j in range(m):
        if j > 0:
            k1 = _rate(zi, A, n, beta, sd, sx)
        k2 = _rate(zi + h * k1, A, n, beta, sd, sx)
        zi = zi + 0.5 * h * (k1 + k2)
        if not abs(zi) <= bound:
            break
    return zi


@njit(cache=True)
def heun_kernel(x, seg, z0, A, n, beta, bound, freeze, max_step, z):  # pragma: no cover
    """Torque at every sample over segments ``x[seg[s]:seg[s+1]]``, each started at ``z0[s]``.

    Returns the index of the first sample whose |z| exceeded ``bound`` (or was not finite), -1 if none;
    after it the segment is NaN (``freeze`` False) or held at +-``bound`` (``freeze`` True)."""
    first_bad = -1
    for s in range(seg.size - 1):
        i0 = seg[s]
        i1 = seg[s + 1]
        zi = z0[s]
        z[i0] = zi
        dead = False
        for i in range(i0, i1 - 1):
            if dead:
                z[i + 1] = zi
                continue
            d = x[i + 1] - x[i]
            if d != 0.0:
                xa = x[i]
                xb = x[i + 1]
                if xa * xb < 0.0:  # sgn x changes at x = 0: integrate up to it exactly, then on
                    zi = _piece(xa, 0.0, zi, A, n, beta, bound, max_step)
                    if abs(zi) <= bound:
                        zi = _piece(0.0, xb, zi, A, n, beta, bound, max_step)
                else:
                    zi = _piece(xa, xb, zi, A, n, beta, bound, max_step)
            if not abs(zi) <= bound:
                if first_bad < 0:
                    first_bad = i + 1
                dead = True
                zi = (-bound if zi < 0.0 else bound) if freeze else np.nan
            z[i + 1] = zi
    return first_bad


@njit(cache=True)
def _rate_sens(z, S, A, n, beta, sd, sx, out):  # pragma: no cover - compiled
    """F(z) and dF/dtheta + dF/dz S (into ``out``)."""
    sz = sgn(z)
    s0 = sd * sz
    s1 = sd * sx
    s2 = sx * sz
    psi = beta[0] * s0 + beta[1] * s1 + beta[2] * s2 + beta[3] * sd + beta[4] * sz + beta[5] * sx
    az = abs(z)
    if az > 0.0:
        lz = math.log(az)
        g = math.exp(n * lz)
        fz = -n * g / az * sz * psi
    else:
        lz = 0.0
        g = 0.0
        fz = 0.0
    out[0] = 1.0 + fz * S[0]
    out[1] = -g * lz * psi + fz * S[1]
    out[2] = -g * s0 + fz * S[2]
    out[3] = -g * s1 + fz * S[3]
    out[4] = -g * s2 + fz * S[4]
    out[5] = -g * sd + fz * S[5]
    out[6] = -g * sz + fz * S[6]
    out[7] = -g * sx + fz * S[7]
    return A - g * psi


@njit(cache=True)
def _piece_sens(xa, xb, zi, S, A, n, beta, bound, max_step, S2, d1, d2):  # pragma: no cover - compiled
    """:func:`_piece` carrying the sensitivities ``S`` (updated in place)."""
    d = xb - xa
    sd = sgn(d)
    sx = sgn(xa + 0.5 * d)
    m, _ = _substeps(d, zi, A, n, beta, sx, max_step, max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG)
    h = d / m
    for _ in range(m):
        k1 = _rate_sens(zi, S, A, n, beta, sd, sx, d1)
        for k in range(8):
            S2[k] = S[k] + h * d1[k]
        k2 = _rate_sens(zi + h * k1, S2, A, n, beta, sd, sx, d2)
        zi = zi + 0.5 * h * (k1 + k2)
        for k in range(8):
            S[k] = S[k] + 0.5 * h * (d1[k] + d2[k])
        if not abs(zi) <= bound:
            break
    return zi


@njit(cache=True)
def heun_sensitivity_kernel(
    x, seg, z0, A, n, beta, bound, freeze, max_step, z, dz, T, rows
):  # pragma: no cover
    """:func:`heun_kernel` and the exact derivatives of its scheme at the samples ``rows`` (increasing),
    ``dz[r, :] = (d z_{rows[r]} / d theta) @ T`` (theta = A, n, beta1..6); derivatives after divergence are
    NaN or 0 (frozen).  The sensitivities are carried along every sample; only the rows asked for are
    projected and stored (a fit compares every k-th sample)."""
    first_bad = -1
    r = 0  # next entry of rows
    S = np.zeros(8)
    S2 = np.zeros(8)
    d1 = np.zeros(8)
    d2 = np.zeros(8)
    for s in range(seg.size - 1):
        i0 = seg[s]
        i1 = seg[s + 1]
        zi = z0[s]
        z[i0] = zi
        for k in range(8):
            S[k] = 0.0
        while r < rows.size and rows[r] < i0:
            r += 1
        if r < rows.size and rows[r] == i0:
            for k in range(8):
                dz[r, k] = 0.0
            r += 1
        dead = False
        for i in range(i0, i1 - 1):
            d = x[i + 1] - x[i]
            if not dead and d != 0.0:
                xa = x[i]
                xb = x[i + 1]
                if xa * xb < 0.0:
                    zi = _piece_sens(xa, 0.0, zi, S, A, n, beta, bound, max_step, S2, d1, d2)
                    if abs(zi) <= bound:
                        zi = _piece_sens(0.0, xb, zi, S, A, n, beta, bound, max_step, S2, d1, d2)
                else:
                    zi = _piece_sens(xa, xb, zi, S, A, n, beta, bound, max_step, S2, d1, d2)
                if not abs(zi) <= bound:
                    if first_bad < 0:
                        first_bad = i + 1
                    dead = True
                    if freeze:
                        zi = -bound if zi < 0.0 else bound
                        for k in range(8):
                            S[k] = 0.0
                    else:
                        zi = np.nan
                        for k in range(8):
                            S[k] = np.nan
            z[i + 1] = zi
            if r < rows.size and rows[r] == i + 1:
                project_row(S, T, dz, r)
                r += 1
    return first_bad
