"""Compiled kernels of the Bouc-Wen state over the angle samples (thesis §6.2.3, Eq 20-23): the literal
Eq 23 recursion and the step-independent integration described in :mod:`.schemes`, each with or without
its forward sensitivities ``d z / d theta`` (theta = A, n, beta1..6).

In this order: the pieces of the rate both schemes share (signs, Psi, ``|z|^n``, inlined), one Eq 23
step, the Heun substeps of the refined scheme along one straight piece of angle (without derivatives, and
with them carried as eight scalars rather than arrays: about 9 % less time per fit, the same bits), and one
loop over segments
and samples (:func:`_sweep`) that serves all four kernels, selected by two flags (a branch per sample that
costs nothing measurable: the per-piece call and the loop are as fast as the four separate kernels they
replace; a further layer of numba ``inline="always"`` around the Heun piece made the sensitivity kernel
about 1.5 times slower, so there is none).  The refined sensitivity kernel, the fits' innermost work, integrates the
trials three or two at a time (:func:`_sweep_lanes`), and so does the kernel without derivatives (the
same sweep, flagged): each substep waits on a logarithm and an exponential of the one before, so
independent trials' substeps interleaved keep the processor busy while each waits (two trials: about 10 %
less time over 1,500 recorded fit calls; three together instead of two and then the third alone: 20-25 %
less for a three-trial call; every operation of each trial the same, so the same bits as one trial after
the other). The lanes are written out, not factored into inlined helpers: helpers returning a lane's state
as tuples made the three-lane kernel slower than two lanes and a single trial. A third lane left empty
costs nothing measurable, so two trials run in the same code with lane c off. The entry kernels take arrays and three small tuples (the
shape parameters, the limits, the sensitivity outputs), unpacked once into the positional arguments of
the compiled internals; numba compiles them once (cached on disk; all compiled code is in this one file,
longer than the usual module for that reason, because numba's cache of a function does not notice a change
in another file).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

IDENTITY8 = np.eye(8)
STIFF_STEP = 0.5  # substep * |dF/dz| at most this at the default substep (Heun is stable to 2 on the
# negative real axis); a shorter max_step_deg shortens this bound in proportion (one knob for fineness)
MAX_SUBSTEPS = 256  # per sample interval: bounded work for any parameter set
DEFAULT_MAX_STEP_DEG = 0.1  # longest substep of the angle (deg)


@njit(cache=True)
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


@njit(cache=True)
def _state_terms(z, n, beta, sd, sx):  # pragma: no cover - compiled
    """``(sgn z, Psi, |z|^n, ln|z|)`` at the state ``z`` on a piece with ``sd``, ``sx`` (one log and one exp:
    the costly part of every rate)."""
    sz = sgn(z)
    g, lz = abs_pow(abs(z), n)
    return sz, shape_psi(beta, sd, sx, sz), g, lz


@njit(cache=True)
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


@njit(cache=True)
def _rate(z, A, n, beta, sd, sx):  # pragma: no cover - compiled
    """``dz/dx = A - |z|^n Psi`` (Eq 20, 22)."""
    g, _ = abs_pow(abs(z), n)
    return A - g * shape_psi(beta, sd, sx, sgn(z))


@njit(cache=True)
def _rate_sens(z, A, n, terms, sd, sx, s0, s1, s2, s3, s4, s5, s6, s7):  # pragma: no cover - compiled
    """F(z) and the eight ``dF/dtheta + dF/dz S`` from the state terms at ``z`` (:func:`_state_terms`) and
    the sensitivities ``S = (s0, ..., s7)``, as a tuple: this is the innermost work of every fit, and
    scalars in registers (not arrays in memory) make the sensitivity kernel about 9 % faster, bit for bit."""
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


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def project_row(sens, T, dz, row):  # pragma: no cover - compiled
    """``dz[row, :] = sens @ T``: one row of the chain-rule Jacobian (``sens`` an array or an 8-tuple)."""
    for c in range(8):
        acc = 0.0
        for k in range(8):
            acc += sens[k] * T[k, c]
        dz[row, c] = acc


@njit(cache=True)
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


@njit(inline="always")
def _sens_substep(zi, h, A, n, beta, sd, sx, terms, S):  # pragma: no cover - compiled
    """One Heun substep with derivatives (:func:`_piece_sens`, :func:`_sens_pieces`), the sensitivities as
    an 8-tuple."""
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


@njit(cache=True)
def _lane_start(seg_index, seg, z0, z, dz, rows):  # pragma: no cover - compiled
    """A lane starting segment ``seg_index``: its first sample's state written, its first row (the
    sensitivities there are zero) and the index of the next row to project."""
    i0 = seg[seg_index]
    z[i0] = z0[seg_index]
    r = np.searchsorted(rows, i0)
    if r < rows.size and rows[r] == i0:
        dz[r, :] = 0.0
        r += 1
    return r


@njit(inline="always")
def _sens_pieces(
    xa_a, xb_a, za, Sa, on_a, xa_b, xb_b, zb, Sb, on_b, xa_c, xb_c, zc, Sc, on_c, A, n, beta, bound, max_step
):  # pragma: no cover - compiled
    """The Heun substeps of one straight angle piece in each of up to three lanes (``on_*``: whether the
    lane has a piece), interleaved substep by substep: the lanes' independent chains of logarithms and
    exponentials overlap in the processor, and each lane's operations are exactly those of
    :func:`_piece_sens`. Returns every lane's state and sensitivities."""
    stiff_step = max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG
    ma = mb = mc = 0
    ha = hb = hc = 0.0
    sda = sxa = sdb = sxb = sdc = sxc = 0.0
    ta = tb = tc = (0.0, 0.0, 0.0, 0.0)
    if on_a:
        d = xb_a - xa_a
        sda = sgn(d)
        sxa = sgn(xa_a + 0.5 * d)
        ma, _, ta = _substeps(d, za, A, n, beta, sda, sxa, max_step, stiff_step)
        ha = d / ma
    if on_b:
        d = xb_b - xa_b
        sdb = sgn(d)
        sxb = sgn(xa_b + 0.5 * d)
        mb, _, tb = _substeps(d, zb, A, n, beta, sdb, sxb, max_step, stiff_step)
        hb = d / mb
    if on_c:
        d = xb_c - xa_c
        sdc = sgn(d)
        sxc = sgn(xa_c + 0.5 * d)
        mc, _, tc = _substeps(d, zc, A, n, beta, sdc, sxc, max_step, stiff_step)
        hc = d / mc
    ja = 0
    jb = 0
    jc = 0
    while ja < ma or jb < mb or jc < mc:
        if ja < ma:
            if ja > 0:
                ta = _state_terms(za, n, beta, sda, sxa)
            za, Sa = _sens_substep(za, ha, A, n, beta, sda, sxa, ta, Sa)
            ja += 1
            if not abs(za) <= bound:
                ma = ja
        if jb < mb:
            if jb > 0:
                tb = _state_terms(zb, n, beta, sdb, sxb)
            zb, Sb = _sens_substep(zb, hb, A, n, beta, sdb, sxb, tb, Sb)
            jb += 1
            if not abs(zb) <= bound:
                mb = jb
        if jc < mc:
            if jc > 0:
                tc = _state_terms(zc, n, beta, sdc, sxc)
            zc, Sc = _sens_substep(zc, hc, A, n, beta, sdc, sxc, tc, Sc)
            jc += 1
            if not abs(zc) <= bound:
                mc = jc
    return za, Sa, zb, Sb, zc, Sc


@njit(cache=True)
def _sweep_lanes(
    x, seg, sa, lanes, z0, A, n, beta, bound, freeze, max_step, stop, z, dz, T, rows, sensitivities
):  # pragma: no cover
    """:func:`_sweep` (refined; with ``sensitivities``, their rows too) of the ``lanes`` (2 or 3) segments
    from ``sa`` on together, sample by sample, their Heun substeps interleaved (:func:`_sens_pieces`, or
    :func:`_plain_pieces` without sensitivities, the lanes then carrying zero sensitivities and ``rows``
    empty): bit for bit the outputs of the one-segment-after-the-other sweep. Returns the first diverged
    sample in segment order or -1; with ``stop``, as soon as that is known (a lane that diverges stops the
    lanes after it)."""
    zero8 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dead8 = zero8 if freeze else (np.nan, np.nan, np.nan, np.nan, np.nan, np.nan, np.nan, np.nan)
    sb = sa + 1
    ra = _lane_start(sa, seg, z0, z, dz, rows)
    rb = _lane_start(sb, seg, z0, z, dz, rows)
    ia, enda = seg[sa], seg[sa + 1] - 1
    ib, endb = seg[sb], seg[sb + 1] - 1
    za = z0[sa]
    zb = z0[sb]
    rc = ic = endc = 0  # lane c: none unless three lanes
    zc = 0.0
    if lanes == 3:
        rc = _lane_start(sa + 2, seg, z0, z, dz, rows)
        ic, endc = seg[sa + 2], seg[sa + 3] - 1
        zc = z0[sa + 2]
    Sa = zero8
    Sb = zero8
    Sc = zero8
    dead_a = dead_b = dead_c = False
    bad_a = bad_b = bad_c = -1
    while ia < enda or ib < endb or ic < endc:
        live_a = ia < enda
        live_b = ib < endb
        live_c = ic < endc
        # the first part of each lane's sample interval (cut at x = 0 where the angle crosses it)
        on_a = on_b = on_c = False
        xa_a = xm_a = xb_a = 0.0
        xa_b = xm_b = xb_b = 0.0
        xa_c = xm_c = xb_c = 0.0
        if live_a and not dead_a:
            xa_a = x[ia]
            xb_a = x[ia + 1]
            if xa_a != xb_a:
                xm_a = 0.0 if xa_a * xb_a < 0.0 else xb_a
                on_a = True
        if live_b and not dead_b:
            xa_b = x[ib]
            xb_b = x[ib + 1]
            if xa_b != xb_b:
                xm_b = 0.0 if xa_b * xb_b < 0.0 else xb_b
                on_b = True
        if live_c and not dead_c:
            xa_c = x[ic]
            xb_c = x[ic + 1]
            if xa_c != xb_c:
                xm_c = 0.0 if xa_c * xb_c < 0.0 else xb_c
                on_c = True
        if on_a or on_b or on_c:
            if sensitivities:
                za, Sa, zb, Sb, zc, Sc = _sens_pieces(
                    xa_a, xm_a, za, Sa, on_a, xa_b, xm_b, zb, Sb, on_b, xa_c, xm_c, zc, Sc, on_c,
                    A, n, beta, bound, max_step,
                )  # fmt: skip
            else:
                za, zb, zc = _plain_pieces(
                    xa_a, xm_a, za, on_a, xa_b, xm_b, zb, on_b, xa_c, xm_c, zc, on_c,
                    A, n, beta, bound, max_step,
                )  # fmt: skip
            # the second part, where the first crossed x = 0 and stayed within range
            on_a = on_a and xm_a != xb_a and abs(za) <= bound
            on_b = on_b and xm_b != xb_b and abs(zb) <= bound
            on_c = on_c and xm_c != xb_c and abs(zc) <= bound
            if (on_a or on_b or on_c) and sensitivities:
                za, Sa, zb, Sb, zc, Sc = _sens_pieces(
                    xm_a, xb_a, za, Sa, on_a, xm_b, xb_b, zb, Sb, on_b, xm_c, xb_c, zc, Sc, on_c,
                    A, n, beta, bound, max_step,
                )  # fmt: skip
            elif on_a or on_b or on_c:
                za, zb, zc = _plain_pieces(
                    xm_a, xb_a, za, on_a, xm_b, xb_b, zb, on_b, xm_c, xb_c, zc, on_c,
                    A, n, beta, bound, max_step,
                )  # fmt: skip
        if live_a:
            if not dead_a and not abs(za) <= bound:
                bad_a = ia + 1
                if stop:
                    return bad_a
                dead_a = True
                za = held(za, bound, freeze)
                Sa = dead8
            z[ia + 1] = za
            if ra < rows.size and rows[ra] == ia + 1:
                project_row(Sa, T, dz, ra)
                ra += 1
            ia += 1
        if live_b:
            if not dead_b and not abs(zb) <= bound:
                bad_b = ib + 1
                dead_b = True
                zb = held(zb, bound, freeze)
                Sb = dead8
                if stop:
                    endb = ib  # only sa (earlier) may still give an earlier index: sc need not go on
                    endc = ic
            z[ib + 1] = zb
            if rb < rows.size and rows[rb] == ib + 1:
                project_row(Sb, T, dz, rb)
                rb += 1
            ib += 1
        if live_c:
            if not dead_c and not abs(zc) <= bound:
                bad_c = ic + 1
                dead_c = True
                zc = held(zc, bound, freeze)
                Sc = dead8
                if stop:
                    endc = ic
            z[ic + 1] = zc
            if rc < rows.size and rows[rc] == ic + 1:
                project_row(Sc, T, dz, rc)
                rc += 1
            ic += 1
    if bad_a >= 0:
        return bad_a
    return bad_b if bad_b >= 0 else bad_c


@njit(inline="always")
def _plain_pieces(
    xa_a, xb_a, za, on_a, xa_b, xb_b, zb, on_b, xa_c, xb_c, zc, on_c, A, n, beta, bound, max_step
):  # pragma: no cover - compiled
    """The Heun substeps of one straight angle piece in each of up to three lanes (``on_*``: whether the
    lane has a piece), without derivatives, interleaved substep by substep: each lane's operations are
    exactly those of :func:`_piece`."""
    stiff_step = max_step * STIFF_STEP / DEFAULT_MAX_STEP_DEG
    ma = mb = mc = 0
    ha = hb = hc = 0.0
    ka = kb = kc = 0.0
    sda = sxa = sdb = sxb = sdc = sxc = 0.0
    if on_a:
        d = xb_a - xa_a
        sda = sgn(d)
        sxa = sgn(xa_a + 0.5 * d)
        ma, ka, _ = _substeps(d, za, A, n, beta, sda, sxa, max_step, stiff_step)
        ha = d / ma
    if on_b:
        d = xb_b - xa_b
        sdb = sgn(d)
        sxb = sgn(xa_b + 0.5 * d)
        mb, kb, _ = _substeps(d, zb, A, n, beta, sdb, sxb, max_step, stiff_step)
        hb = d / mb
    if on_c:
        d = xb_c - xa_c
        sdc = sgn(d)
        sxc = sgn(xa_c + 0.5 * d)
        mc, kc, _ = _substeps(d, zc, A, n, beta, sdc, sxc, max_step, stiff_step)
        hc = d / mc
    ja = jb = jc = 0
    while ja < ma or jb < mb or jc < mc:
        if ja < ma:
            if ja > 0:
                ka = _rate(za, A, n, beta, sda, sxa)
            k2 = _rate(za + ha * ka, A, n, beta, sda, sxa)
            za = za + 0.5 * ha * (ka + k2)
            ja += 1
            if not abs(za) <= bound:
                ma = ja
        if jb < mb:
            if jb > 0:
                kb = _rate(zb, A, n, beta, sdb, sxb)
            k2 = _rate(zb + hb * kb, A, n, beta, sdb, sxb)
            zb = zb + 0.5 * hb * (kb + k2)
            jb += 1
            if not abs(zb) <= bound:
                mb = jb
        if jc < mc:
            if jc > 0:
                kc = _rate(zc, A, n, beta, sdc, sxc)
            k2 = _rate(zc + hc * kc, A, n, beta, sdc, sxc)
            zc = zc + 0.5 * hc * (kc + k2)
            jc += 1
            if not abs(zc) <= bound:
                mc = jc
    return za, zb, zc


# The entry points take three small records (tuples, unpacked once here at the top of the compiled code):
# shape = (A, n, beta) with beta a float64 array of 6; limits = (bound, freeze, max_step, stop) (max_step
# unused by Eq 23); sens = (dz, T, rows) for the kernels with derivatives (see :func:`_sweep`).


@njit(cache=True)
def recursion_kernel(x, seg, z0, shape, limits, z):  # pragma: no cover - compiled
    """Eq 23 over the segments (see :func:`_sweep`): writes ``z``, returns the first diverged index or -1."""
    A, n, beta = shape
    bound, freeze, _, stop = limits
    dz, rows = np.empty((0, 8)), np.empty(0, dtype=np.int64)  # none
    return _sweep(x, seg, z0, A, n, beta, bound, freeze, 0.0, stop, z, dz, IDENTITY8, rows, False, False)


@njit(cache=True)
def sensitivity_kernel(x, seg, z0, shape, limits, z, sens):  # pragma: no cover - compiled
    """Eq 23 and its exact derivatives at ``rows`` (see :func:`_sweep`, :func:`eq23_step_sens`)."""
    A, n, beta = shape
    bound, freeze, _, stop = limits
    dz, T, rows = sens
    return _sweep(x, seg, z0, A, n, beta, bound, freeze, 0.0, stop, z, dz, T, rows, False, True)


@njit(cache=True)
def _sweep_refined(
    x, seg, z0, A, n, beta, bound, freeze, step, stop, z, dz, T, rows, sensitivities
):  # pragma: no cover
    """The refined :func:`_sweep` (with or without ``sensitivities``) of every segment: three at a time,
    four left as two pairs, two left as a pair (:func:`_sweep_lanes`), one alone; the same bits as one
    after the other, and the first diverged sample in segment order (with ``stop``, at once)."""
    n_seg = seg.size - 1
    first_bad = -1
    s = 0
    while s < n_seg:
        left = n_seg - s
        if left >= 2:
            lanes = 3 if left >= 3 and left != 4 else 2
            bad = _sweep_lanes(
                x, seg, s, lanes, z0, A, n, beta, bound, freeze, step, stop, z, dz, T, rows, sensitivities
            )
            s += lanes
        else:
            bad = _sweep(
                x, seg[s:], z0[s:], A, n, beta, bound, freeze, step, stop, z, dz, T, rows, True, sensitivities
            )
            s += 1
        if bad >= 0:
            if stop:
                return bad
            if first_bad < 0:
                first_bad = bad
    return first_bad


@njit(cache=True)
def heun_kernel(x, seg, z0, shape, limits, z):  # pragma: no cover - compiled
    """The step-independent integration (:mod:`.schemes`) over the segments (see :func:`_sweep`), several
    at a time (:func:`_sweep_refined`)."""
    A, n, beta = shape
    bound, freeze, step, stop = limits
    dz, rows = np.empty((0, 8)), np.empty(0, dtype=np.int64)  # none
    return _sweep_refined(x, seg, z0, A, n, beta, bound, freeze, step, stop, z, dz, IDENTITY8, rows, False)


@njit(cache=True)
def heun_sensitivity_kernel(x, seg, z0, shape, limits, z, sens):  # pragma: no cover - compiled
    """:func:`heun_kernel` and the exact derivatives of its scheme at ``rows`` (see :func:`_sweep`), several
    segments at a time (:func:`_sweep_refined`)."""
    A, n, beta = shape
    bound, freeze, step, stop = limits
    dz, T, rows = sens
    return _sweep_refined(x, seg, z0, A, n, beta, bound, freeze, step, stop, z, dz, T, rows, True)


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
