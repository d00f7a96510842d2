"""Compiled kernels of the Bouc-Wen state over the angle samples (thesis §6.2.3, Eq 20-23): the literal
Eq 23 recursion and the step-independent integration of Eq 20-22 described in :mod:`.schemes`, each with
or without its forward sensitivities ``d z / d theta`` (theta = A, n, beta1..6).

One loop over segments and samples (:func:`_sweep`, entered by :func:`kernel`) serves both schemes with or
without derivatives; the segments (trials) are integrated one after the other, each from its own starting
torque.  All compiled code is in this one file: numba's cache of a function does not notice a change in
another file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from protocol_runner.numba_cache import cache_enabled

CACHE = cache_enabled()  # numba caches on disk unless no directory is writable (numba_cache.py)

IDENTITY8 = np.eye(8)
STIFF_STEP = 0.5  # substep * |dF/dz| at most this at the default substep (Heun is stable to 2 on the
# negative real axis); a shorter max_step_deg shortens this bound in proportion (one knob for fineness)
MAX_SUBSTEPS = 256  # per sample interval: bounded work for any parameter set
DEFAULT_MAX_STEP_DEG = 0.1  # longest substep of the angle (deg)


@njit(cache=CACHE)
def sgn(v: float) -> float:  # pragma: no cover - compiled
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@njit(inline="always")
def shape_psi(beta, sd, sx, sz):  # pragma: no cover - compiled
    """Psi of Eq 22, ``beta1 sd sz + beta2 sd sx + beta3 sx sz + beta4 sd + beta5 sz + beta6 sx`` with
    ``sd = sgn(dx)``, ``sx = sgn(x)``, ``sz = sgn(z)``."""
    return (
        beta[0] * sd * sz + beta[1] * sd * sx + beta[2] * sx * sz + beta[3] * sd + beta[4] * sz + beta[5] * sx
    )


@njit(inline="always")
def sign_terms(sd, sx, sz, sig):  # pragma: no cover - compiled
    """The six sign products of Eq 22 (``d Psi / d beta``) into ``sig``."""
    sig[0] = sd * sz
    sig[1] = sd * sx
    sig[2] = sx * sz
    sig[3] = sd
    sig[4] = sz
    sig[5] = sx


@njit(inline="always")
def abs_pow(az, n):  # pragma: no cover - compiled
    """``(|z|^n, ln|z|)`` for ``az = |z|``, the power as ``exp(n ln|z|)`` (the same bits in every kernel);
    ``(0, 0)`` at ``z = 0`` (the limit of ``|z|^n ln|z|``)."""
    if az > 0.0:
        lz = math.log(az)
        return math.exp(n * lz), lz
    return 0.0, 0.0


@njit(inline="always")
def held(z, bound, freeze):  # pragma: no cover - compiled
    """The state after divergence: +-``bound`` (``freeze``, the fitter's finite penalty) or NaN."""
    return (-bound if z < 0.0 else bound) if freeze else np.nan


@njit(inline="always")
def eq23_step(xa, xb, zi, A, n, beta):  # pragma: no cover - compiled
    """Eq 23: ``z_{i+1} = z_i + (x_{i+1} - x_i) (A - |z_i|^n Psi_i)``."""
    d = xb - xa
    psi = shape_psi(beta, sgn(d), sgn(xa), sgn(zi))
    g, _ = abs_pow(abs(zi), n)
    return zi + d * (A - g * psi)


@njit(inline="always")
def eq23_step_sens(xa, xb, zi, S, A, n, beta, sig):  # pragma: no cover - compiled
    """:func:`eq23_step` and its exact derivatives ``S = d z / d theta`` (theta = A, n, beta1..6, updated in
    place).  Differentiating Eq 23 (the signs are piecewise constant, so their derivative is zero almost
    everywhere) gives, with ``g_i = |z_i|^n`` and ``s_i`` the six signs::

        dz_{i+1} = dz_i + d_i [dA - dg_i Psi_i - g_i (s_i . dbeta)]
        dg_i = n |z_i|^(n-1) sgn(z_i) dz_i + g_i ln|z_i| dn

    At ``z_i = 0`` both terms of ``dg_i`` are taken as 0 (for n < 1 the first has no finite limit and 0
    is the one-sided convention)."""
    d = xb - xa
    sd = sgn(d)
    sx = sgn(xa)
    sz = sgn(zi)
    sign_terms(sd, sx, sz, sig)
    psi = shape_psi(beta, sd, sx, sz)
    az = abs(zi)
    g, lz = abs_pow(az, n)
    coef = n * g / az * sz if az > 0.0 else 0.0
    dg0 = coef * S[0]
    dg1 = coef * S[1] + g * lz
    S[0] = S[0] + d * (1.0 - dg0 * psi)
    S[1] = S[1] - d * dg1 * psi
    for k in range(6):
        dgk = coef * S[k + 2]
        S[k + 2] = S[k + 2] - d * (dgk * psi + g * sig[k])
    return zi + d * (A - g * psi)


@njit(cache=CACHE)
def _state_terms(z, n, beta, sd, sx):  # pragma: no cover - compiled
    """``(sgn z, Psi, |z|^n, ln|z|)`` at the state ``z`` on a piece with ``sd``, ``sx`` (one log and one exp:
    the costly part of every rate)."""
    sz = sgn(z)
    g, lz = abs_pow(abs(z), n)
    return sz, shape_psi(beta, sd, sx, sz), g, lz


@njit(cache=CACHE)
def _substeps(d, zi, A, n, beta, sd, sx, max_step, stiff_step):  # pragma: no cover - compiled
    """Substep count of a piece, the rate ``dz/dx`` at its start and the state terms there
    (:func:`_state_terms`: one power of |z| for all three, and the first substep reuses them)."""
    terms = _state_terms(zi, n, beta, sd, sx)
    _, psi, g, _ = terms
    az = abs(zi)
    stiff = n * g / az * abs(psi) if az > 0.0 else 0.0
    rate = max(1.0 / max_step, stiff / stiff_step)
    m = math.ceil(abs(d) * rate) if math.isfinite(rate) else MAX_SUBSTEPS
    return max(1, min(MAX_SUBSTEPS, m)), A - g * psi, terms


@njit(cache=CACHE)
def _rate(z, A, n, beta, sd, sx):  # pragma: no cover - compiled
    """``dz/dx = A - |z|^n Psi`` (Eq 20, 22)."""
    g, _ = abs_pow(abs(z), n)
    return A - g * shape_psi(beta, sd, sx, sgn(z))


@njit(cache=CACHE)
def _rate_sens(z, A, n, terms, sd, sx, s0, s1, s2, s3, s4, s5, s6, s7):  # pragma: no cover - compiled
    """F(z) and the eight ``dF/dtheta + dF/dz S`` from the state terms at ``z`` (:func:`_state_terms`) and
    the sensitivities ``S = (s0, ..., s7)``, as a tuple (the innermost work of every fit: scalars that
    stay in registers rather than an array in memory)."""
    sz, psi, g, lz = terms
    az = abs(z)
    fz = -n * g / az * sz * psi if az > 0.0 else 0.0
    return (
        A - g * psi,
        1.0 + fz * s0,
        -g * lz * psi + fz * s1,
        -g * (sd * sz) + fz * s2,
        -g * (sd * sx) + fz * s3,
        -g * (sx * sz) + fz * s4,
        -g * sd + fz * s5,
        -g * sz + fz * s6,
        -g * sx + fz * s7,
    )


@njit(cache=CACHE)
def _piece(xa, xb, zi, A, n, beta, bound, max_step):  # pragma: no cover - compiled
    """Heun substeps along the straight angle piece ``xa -> xb`` on which sgn x does not change."""
    d = xb - xa
    sd = sgn(d)
    sx = sgn(xa + 0.5 * d)
    stiff_step = max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG
    m, k1, _ = _substeps(d, zi, A, n, beta, sd, sx, max_step, stiff_step)
    h = d / m
    for j in range(m):
        if j > 0:  # the first substep's rate came with its count
            k1 = _rate(zi, A, n, beta, sd, sx)
        k2 = _rate(zi + h * k1, A, n, beta, sd, sx)
        zi = zi + 0.5 * h * (k1 + k2)
        if not abs(zi) <= bound:
            break
    return zi


@njit(inline="always")
def _sens_substep(zi, h, A, n, beta, sd, sx, terms, S):  # pragma: no cover - compiled
    """One Heun substep with derivatives (:func:`_piece_sens`), the sensitivities as an 8-tuple."""
    s0, s1, s2, s3, s4, s5, s6, s7 = S
    k1, a0, a1, a2, a3, a4, a5, a6, a7 = _rate_sens(zi, A, n, terms, sd, sx, s0, s1, s2, s3, s4, s5, s6, s7)
    z2 = zi + h * k1
    k2, b0, b1, b2, b3, b4, b5, b6, b7 = _rate_sens(
        z2,
        A,
        n,
        _state_terms(z2, n, beta, sd, sx),
        sd,
        sx,
        s0 + h * a0,
        s1 + h * a1,
        s2 + h * a2,
        s3 + h * a3,
        s4 + h * a4,
        s5 + h * a5,
        s6 + h * a6,
        s7 + h * a7,
    )
    half = 0.5 * h
    out = (
        s0 + half * (a0 + b0),
        s1 + half * (a1 + b1),
        s2 + half * (a2 + b2),
        s3 + half * (a3 + b3),
        s4 + half * (a4 + b4),
        s5 + half * (a5 + b5),
        s6 + half * (a6 + b6),
        s7 + half * (a7 + b7),
    )
    return zi + half * (k1 + k2), out


@njit(cache=CACHE)
def _piece_sens(xa, xb, zi, A, n, beta, bound, max_step, S):  # pragma: no cover - compiled
    """:func:`_piece` carrying the derivatives ``S = d z / d theta`` along (updated in place at the end;
    in between they are eight scalars, see :func:`_rate_sens`; each substep is :func:`_sens_substep`)."""
    d = xb - xa
    sd = sgn(d)
    sx = sgn(xa + 0.5 * d)
    stiff_step = max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG
    m, _, terms = _substeps(d, zi, A, n, beta, sd, sx, max_step, stiff_step)
    h = d / m
    sens = (S[0], S[1], S[2], S[3], S[4], S[5], S[6], S[7])
    for j in range(m):
        if j > 0:  # the first substep's terms came with its count
            terms = _state_terms(zi, n, beta, sd, sx)
        zi, sens = _sens_substep(zi, h, A, n, beta, sd, sx, terms, sens)
        if not abs(zi) <= bound:
            break
    S[0], S[1], S[2], S[3], S[4], S[5], S[6], S[7] = sens
    return zi


@njit(cache=CACHE)
def project_row(sens, T, dz, row):  # pragma: no cover - compiled
    """``dz[row, :] = sens @ T``: one row of the chain-rule Jacobian."""
    for c in range(8):
        acc = 0.0
        for k in range(8):
            acc += sens[k] * T[k, c]
        dz[row, c] = acc


@njit(cache=CACHE)
def _sweep(
    x, seg, z0, A, n, beta, bound, freeze, max_step, stop, z, dz, T, rows, refined, sensitivities
):  # pragma: no cover
    """The state at every sample over consecutive segments ``x[seg[s]:seg[s+1]]``, each restarted at
    ``z0[s]``, by Eq 23 or (``refined``) by Heun substeps of at most ``max_step`` (:func:`_piece`; an
    interval on which the angle crosses 0 is cut there); with ``sensitivities`` also
    ``dz[r, :] = (d z_{rows[r]} / d theta) @ T`` at the samples ``rows`` (increasing; the sensitivities are
    carried along every sample, only those rows are projected).

    Returns the index of the first sample whose |z| exceeded ``bound`` (or was not finite), -1 if none.
    After divergence the rest of that segment is NaN (``freeze`` False) or held at +-``bound`` (``freeze``
    True, the finite penalty used by the fitter), its derivatives NaN or 0, and the other segments are
    integrated in full; with ``stop`` it returns at once instead, ``z`` and ``dz`` then left incomplete (a
    check whose only use is whether it diverges).  Without a divergence ``stop`` changes nothing.
    """
    first_bad = -1
    r = 0  # next entry of rows
    S = np.zeros(8)
    sig = np.zeros(6)
    for s in range(seg.size - 1):
        i0 = seg[s]
        i1 = seg[s + 1]
        zi = z0[s]
        z[i0] = zi
        if sensitivities:
            S[:] = 0.0
            while r < rows.size and rows[r] < i0:
                r += 1
            if r < rows.size and rows[r] == i0:
                dz[r, :] = 0.0
                r += 1
        dead = False
        for i in range(i0, i1 - 1):
            xa = x[i]
            xb = x[i + 1]
            if dead:
                pass
            elif not refined:
                zi = (
                    eq23_step_sens(xa, xb, zi, S, A, n, beta, sig)
                    if sensitivities
                    else eq23_step(xa, xb, zi, A, n, beta)
                )
            elif xa != xb:
                # Heun substeps along the straight angle piece, cut at x = 0 where sgn x changes
                xm = 0.0 if xa * xb < 0.0 else xb
                if sensitivities:
                    zi = _piece_sens(xa, xm, zi, A, n, beta, bound, max_step, S)
                    if xm != xb and abs(zi) <= bound:
                        zi = _piece_sens(xm, xb, zi, A, n, beta, bound, max_step, S)
                else:
                    zi = _piece(xa, xm, zi, A, n, beta, bound, max_step)
                    if xm != xb and abs(zi) <= bound:
                        zi = _piece(xm, xb, zi, A, n, beta, bound, max_step)
            if not dead and not abs(zi) <= bound:
                if first_bad < 0:
                    first_bad = i + 1
                if stop:
                    return first_bad
                dead = True
                zi = held(zi, bound, freeze)
                S[:] = 0.0 if freeze else np.nan
            z[i + 1] = zi
            if sensitivities and r < rows.size and rows[r] == i + 1:
                project_row(S, T, dz, r)
                r += 1
    return first_bad


NO_SENSITIVITY = (np.empty((0, 8)), IDENTITY8, np.empty(0, dtype=np.int64))  # sens of a kernel call without


@njit(cache=CACHE)
def kernel(x, seg, z0, shape, limits, z, sens, refined, sensitivities):  # pragma: no cover - compiled
    """:func:`_sweep` (Eq 23, or ``refined``; with ``sensitivities`` also the derivatives) with its
    arguments in three small records, unpacked here once: ``shape = (A, n, beta)`` with beta a float64
    array of 6; ``limits = (bound, freeze, max_step, stop)`` (max_step unused by Eq 23); ``sens = (dz, T,
    rows)`` (:data:`NO_SENSITIVITY` without derivatives)."""
    A, n, beta = shape
    bound, freeze, step, stop = limits
    dz, T, rows = sens
    return _sweep(x, seg, z0, A, n, beta, bound, freeze, step, stop, z, dz, T, rows, refined, sensitivities)


@njit(cache=CACHE)
def gram(J):  # pragma: no cover
    """``J.T @ J`` in plain loops."""
    k = J.shape[1]
    G = np.zeros((k, k))
    for i in range(J.shape[0]):
        for a in range(k):
            ja = J[i, a]
            for b in range(a, k):
                G[a, b] += ja * J[i, b]
    for a in range(k):
        for b in range(a):
            G[a, b] = G[b, a]
    return G


@njit(cache=CACHE)
def sum_sq_diff(z, y):  # pragma: no cover
    """``sum((z - y)**2)`` in a plain loop."""
    acc = 0.0
    for i in range(z.size):
        d = z[i] - y[i]
        acc += d * d
    return acc
