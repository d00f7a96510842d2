"""Compiled kernels: the Eq 23 recursion and its forward sensitivities (thesis §6.2.3).

The kernels take arrays and plain numbers so numba compiles them once (cached on disk).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

IDENTITY8 = np.eye(8)


@njit(cache=True)
def sgn(v: float) -> float:  # pragma: no cover - compiled
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@njit(cache=True)
def recursion_kernel(x, seg, z0, A, n, beta, bound, freeze, z):  # pragma: no cover
    """Eq 23 over consecutive segments ``x[seg[s]:seg[s+1]]``, each restarted at ``z0[s]``.

    Writes ``z`` and returns the index of the first sample whose |z| exceeded ``bound`` (or was not finite),
    -1 if none.  After divergence the rest of that segment is NaN (``freeze`` False) or held at
    +-``bound`` (``freeze`` True, the finite penalty used by the fitter).
    """
    first_bad = -1
    b0 = beta[0]
    b1 = beta[1]
    b2 = beta[2]
    b3 = beta[3]
    b4 = beta[4]
    b5 = beta[5]
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
            xi = x[i]
            d = x[i + 1] - xi
            sd = sgn(d)
            sx = sgn(xi)
            sz = sgn(zi)
            psi = b0 * sd * sz + b1 * sd * sx + b2 * sx * sz + b3 * sd + b4 * sz + b5 * sx
            az = abs(zi)
            # exp(n ln|z|) rather than az**n: bit-identical to the sensitivity kernel
            g = math.exp(n * math.log(az)) if az > 0.0 else 0.0
            znew = zi + d * (A - g * psi)
            if abs(znew) <= bound:
                zi = znew
            else:
                if first_bad < 0:
                    first_bad = i + 1
                dead = True
                zi = (-bound if znew < 0.0 else bound) if freeze else np.nan
            z[i + 1] = zi
    return first_bad


@njit(cache=True)
def project_row(sens, T, dz, row):  # pragma: no cover - compiled
    """``dz[row, :] = sens @ T``: one row of the chain-rule Jacobian (both sensitivity kernels)."""
    for c in range(8):
        acc = 0.0
        for k in range(8):
            acc += sens[k] * T[k, c]
        dz[row, c] = acc


@njit(cache=True)
def sensitivity_kernel(x, seg, z0, A, n, beta, bound, freeze, z, dz, T):  # pragma: no cover
    """Eq 23 and its exact derivatives ``d z_i / d theta_k``, theta = (A, n, beta1..6), written as
    ``dz[i, :] = (d z_i / d theta) @ T`` (``T`` = identity for the plain derivatives; the fitter passes its
    chain-rule matrix so that no separate pass over the Jacobian is needed).

    Differentiating Eq 23 (the signs are piecewise constant, so their derivative is zero almost
    everywhere) gives, with ``g_i = |z_i|^n`` and ``s_i`` the six signs of Eq 23::

        dz_{i+1} = dz_i + d_i [dA - dg_i Psi_i - g_i (s_i . dbeta)]
        dg_i = n |z_i|^(n-1) sgn(z_i) dz_i + g_i ln|z_i| dn

    At ``z_i = 0`` both terms of ``dg_i`` are taken as 0 (the limit of ``|z|^n ln|z|``; for n < 1 the
    first term has no finite limit and 0 is the one-sided convention).  Divergence handling as in
    :func:`recursion_kernel`; derivatives after divergence are NaN or 0 (frozen).
    """
    first_bad = -1
    sens = np.zeros(8)
    sig = np.zeros(6)
    for s in range(seg.size - 1):
        i0 = seg[s]
        i1 = seg[s + 1]
        zi = z0[s]
        z[i0] = zi
        for k in range(8):
            sens[k] = 0.0
            dz[i0, k] = 0.0
        dead = False
        for i in range(i0, i1 - 1):
            if dead:
                z[i + 1] = zi
                for c in range(8):
                    acc = 0.0
                    for k in range(8):
                        acc += sens[k] * T[k, c]
                    dz[i + 1, c] = acc
                continue
            xi = x[i]
            d = x[i + 1] - xi
            sd = sgn(d)
            sx = sgn(xi)
            sz = sgn(zi)
            sig[0] = sd * sz
            sig[1] = sd * sx
            sig[2] = sx * sz
            sig[3] = sd
            sig[4] = sz
            sig[5] = sx
            psi = 0.0
            for k in range(6):
                psi += beta[k] * sig[k]
            az = abs(zi)
            if az > 0.0:
                lz = math.log(az)
                g = math.exp(n * lz)
                coef = n * g / az * sz
            else:
                lz = 0.0
                g = 0.0
                coef = 0.0
            znew = zi + d * (A - g * psi)
            if abs(znew) <= bound:
                # derivatives (use the old sens values on the right-hand side)
                dg0 = coef * sens[0]
                dg1 = coef * sens[1] + g * lz
                sens[0] = sens[0] + d * (1.0 - dg0 * psi)
                sens[1] = sens[1] - d * dg1 * psi
                for k in range(6):
                    dgk = coef * sens[k + 2]
                    sens[k + 2] = sens[k + 2] - d * (dgk * psi + g * sig[k])
                zi = znew
            else:
                if first_bad < 0:
                    first_bad = i + 1
                dead = True
                if freeze:
                    zi = -bound if znew < 0.0 else bound
                    for k in range(8):
                        sens[k] = 0.0
                else:
                    zi = np.nan
                    for k in range(8):
                        sens[k] = np.nan
            z[i + 1] = zi
            project_row(sens, T, dz, i + 1)
    return first_bad


@njit(cache=True)
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


@njit(cache=True)
def sum_sq_diff(z, y):  # pragma: no cover
    """``sum((z - y)**2)`` in a plain loop."""
    acc = 0.0
    for i in range(z.size):
        d = z[i] - y[i]
        acc += d * d
    return acc
