"""Data-driven starting points of the Bouc-Wen fit: the thesis's Figure 56 guess and an equation-error
least-squares guess (Eq 23 with the measured torque on the right-hand side)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .params import BoucWenParams, FloatArray, phase_of_samples


def thesis_start(x: FloatArray, y: FloatArray, seg: npt.NDArray[np.int64]) -> BoucWenParams:
    """Figure 56 initial guess: A = 1, n = 1 and, for each Table 4 phase, the typical ``Psi`` obtained by
    solving Eq 23 for ``Psi`` on every step where it is defined (``(A - dz/dx) / |z|^n``), then Eq 25.

    The thesis averages; the median is used here so that noise on steep steps does not dominate.
    """
    A0, n0 = 1.0, 1.0
    psi = np.zeros(6)
    per_phase: list[list[FloatArray]] = [[] for _ in range(6)]
    for s in range(seg.size - 1):
        xs = x[seg[s] : seg[s + 1]]
        ys = y[seg[s] : seg[s + 1]]
        if xs.size < 2:
            continue
        phase = phase_of_samples(xs, ys)
        d = np.diff(xs)
        ok = (phase > 0) & (d != 0.0) & (ys[:-1] != 0.0)
        est = (A0 - np.diff(ys)[ok] / d[ok]) / np.abs(ys[:-1][ok]) ** n0
        ph = phase[ok]
        for k in range(6):
            per_phase[k].append(est[ph == k + 1])
    for k in range(6):
        vals = np.concatenate(per_phase[k]) if per_phase[k] else np.empty(0)
        vals = vals[np.isfinite(vals)]
        psi[k] = float(np.median(vals)) if vals.size else 0.0
    return BoucWenParams.from_phases(A0, n0, psi)


def equation_error_start(
    x: FloatArray, y: FloatArray, seg: npt.NDArray[np.int64], n_grid: FloatArray
) -> BoucWenParams | None:
    """Equation-error guess: with the measured torque on the right-hand side of Eq 23, the step
    ``y_{i+1} - y_i = d_i A - d_i |y_i|^n (s_i . beta)`` is linear in (A, beta) for a given n; solve it by
    linear least squares on a grid of n and keep the best."""
    rows: list[FloatArray] = []
    rhs: list[FloatArray] = []
    for s in range(seg.size - 1):
        xs = x[seg[s] : seg[s + 1]]
        ys = y[seg[s] : seg[s + 1]]
        if xs.size < 2:
            continue
        d = np.diff(xs)
        xi = xs[:-1]
        zi = ys[:-1]
        sd, sx, sz = np.sign(d), np.sign(xi), np.sign(zi)
        sig = np.stack([sd * sz, sd * sx, sx * sz, sd, sz, sx], axis=1)
        keep = d != 0.0
        rows.append(np.column_stack([d, np.abs(zi), sig * d[:, None]])[keep])
        rhs.append(np.diff(ys)[keep])
    if not rows:
        return None
    base = np.concatenate(rows)
    b = np.concatenate(rhs)
    if b.size < 8:
        return None
    best: tuple[float, BoucWenParams] | None = None
    absz = base[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        for n in n_grid:
            g = np.where(absz > 0.0, absz**n, 0.0)
            M = np.column_stack([base[:, 0], -g[:, None] * base[:, 2:]])
            coef, *_ = np.linalg.lstsq(M, b, rcond=None)
            if not np.all(np.isfinite(coef)):
                continue
            r = M @ coef - b
            sse = float(r @ r)
            cand = BoucWenParams(A=max(coef[0], 0.0), n=float(n), beta=tuple(coef[1:]))
            if best is None or sse < best[0]:
                best = (sse, cand)
    return None if best is None else best[1]
