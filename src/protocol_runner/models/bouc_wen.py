"""Generalised Bouc-Wen hysteresis model of a joint's torque-angle loop (thesis §6.2, Eq 19-25).

The thesis extends the Bouc-Wen model (Eq 20, ``dz = dx [A - |z|^n Psi]``) with a shape function that also
depends on the sign of the angle, so that asymmetric loops (a joint that behaves differently when stretched
and compressed) can be represented (§6.2.3, Eq 22)::

    Psi = b1 sgn(dx z) + b2 sgn(dx x) + b3 sgn(x z) + b4 sgn(dx) + b5 sgn(z) + b6 sgn(x)

and discretises it with the explicit first-order recursion of Eq 23::

    z_0 = initial torque
    z_{i+1} = z_i + (x_{i+1} - x_i) [A - |z_i|^n Psi_i]

where ``x`` is the joint angle in degrees and ``z`` is the torque in N*m (so ``A`` is in N*m/deg and each
``beta_k`` in N*m^(1-n)/deg).  (Eq 22 is garbled in the available copy of the thesis; the sign terms above
are those of Eq 23, which Table 4 confirms.)  The six sign patterns met on a centred loop are the six
phases of Table 4; their shape values ``psi = M24 @ beta`` (Eq 24) are inverted by Eq 25,
``beta = M25 @ psi``.  The other two sign patterns, (x > 0, dx > 0, z < 0) and (x < 0, dx < 0, z > 0), are
not phases of Table 4 but Eq 23 still applies there; with the Figure 57 parameters the second one is
unstable (a recursion started there with a few N*m diverges), which is why divergence is detected.

Units and conventions:

* ``sgn(0) = 0``, exactly as the signum function in Eq 23; a sample where the angle does not move leaves the
  torque unchanged.
* The recursion depends only on the sequence of angle increments, not on time (it is rate-independent), so
  fitting a decimated copy of smooth data is legitimate; the explicit-Euler error of Eq 23 grows with the
  step size, which is why only already-filtered data should be decimated (see :func:`fit`).
* The thesis centres each trial on (0, 0) before fitting (note under Table 4).  :func:`fit` does *not*
  centre: the caller (the analysis pipeline) does, and the model is fitted to the samples exactly as given.

Fitting (§6.2.3, Figure 56) minimises the squared difference between measured and simulated torque with
``scipy.optimize.least_squares`` and an analytic Jacobian obtained by differentiating Eq 23 (forward
sensitivities, computed in the same numba pass as the torque).  §6.2.5 notes that the thesis fit "depends a
lot on the initial conditions"; this implementation starts from the thesis's data-driven guess (Figure 56),
from an equation-error least-squares guess, and from quasi-random points spread over the parameter bounds,
and keeps the best optimum, so the result does not depend on any single starting point.

Performance: the numba kernels are compiled once (cached on disk); a fit of one configuration (three 65 s
trials at 1 kHz) takes about 0.1 s on a busy 2-core machine (``benchmarks/bench_bouc_wen.py``) - provided
BLAS runs single-threaded.  The solver's linear algebra on the tall 8-column Jacobian (SVD, products) goes
through OpenBLAS, whose worker threads make each call cost milliseconds when the cores are busy: the same
fit then takes about 1.2 s.  Set ``OPENBLAS_NUM_THREADS=1`` in the environment before numpy is imported.
This module keeps its own tall-matrix work (Jacobian chain rule, Gram matrix, sums of squares) in numba
loops for that reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from numba import njit
from scipy.optimize import least_squares
from scipy.stats import qmc

from protocol_runner.errors import InvalidInput

__all__ = [
    "DEFAULT_BOUNDS",
    "EQ24_PHASE_MATRIX",
    "EQ25_BETA_MATRIX",
    "PARAM_NAMES",
    "BoucWenBounds",
    "BoucWenFit",
    "BoucWenParams",
    "betas_from_phases",
    "cross_validate",
    "fit",
    "fit_trials",
    "phase_of_samples",
    "phase_values",
    "simulate",
    "simulate_sensitivity",
]

FloatArray = npt.NDArray[np.float64]

PARAM_NAMES: tuple[str, ...] = ("A", "n", "beta1", "beta2", "beta3", "beta4", "beta5", "beta6")
"""Order of the eight model parameters in every vector, Jacobian column and ``param_std``."""

EQ24_PHASE_MATRIX: FloatArray = np.array(
    [
        [1, 1, 1, 1, 1, 1],
        [-1, -1, 1, -1, 1, 1],
        [1, -1, -1, -1, -1, 1],
        [1, 1, 1, -1, -1, -1],
        [-1, -1, 1, 1, -1, -1],
        [1, -1, -1, 1, 1, -1],
    ],
    dtype=np.float64,
)
"""Eq 24 (Table 4): ``psi = EQ24_PHASE_MATRIX @ beta``, rows are phases 1-6."""

EQ25_BETA_MATRIX: FloatArray = 0.25 * np.array(
    [
        [1, 0, 1, 1, 0, 1],
        [0, -1, -1, 0, -1, -1],
        [1, 1, 0, 1, 1, 0],
        [1, -1, 0, -1, 1, 0],
        [0, 1, -1, 0, -1, 1],
        [1, 0, 1, -1, 0, -1],
    ],
    dtype=np.float64,
)
"""Eq 25: ``beta = EQ25_BETA_MATRIX @ psi`` (1/4 times the matrix printed in the thesis)."""

# Table 4 phases as (sgn x, sgn dx, sgn z); the two remaining sign patterns (+,+,-) and (-,-,+) are not
# phases of Table 4 (Eq 23 still defines Psi there) and are reported as phase 0 by phase_of_samples().
_TABLE4_SIGNS: tuple[tuple[int, int, int], ...] = (
    (1, 1, 1),
    (1, -1, 1),
    (1, -1, -1),
    (-1, -1, -1),
    (-1, 1, -1),
    (-1, 1, 1),
)

DEFAULT_SIMULATION_BOUND_NM = 1.0e6
"""|z| beyond which :func:`simulate` declares the recursion diverged (the rest of the output is NaN)."""


@dataclass(frozen=True)
class BoucWenParams:
    """Parameters of the generalised Bouc-Wen model (Eq 22-23).

    A: scale of the hysteretic stiffness, N*m per degree (``dz/dx`` at ``z = 0``).
    n: exponent of ``|z|`` (dimensionless, > 0), controls the sharpness of the loop's knees.
    beta: the six shape coefficients of Eq 22, in N*m^(1-n) per degree.
    """

    A: float
    n: float
    beta: tuple[float, float, float, float, float, float]

    def __post_init__(self) -> None:
        try:
            A = float(self.A)
            n = float(self.n)
            beta = tuple(float(b) for b in self.beta)
        except (TypeError, ValueError):
            raise InvalidInput(
                f"BoucWenParams needs numbers: A, n and 6 betas, got A={self.A!r}, n={self.n!r}, "
                f"beta={self.beta!r}"
            ) from None
        if len(beta) != 6:
            raise InvalidInput(f"BoucWenParams.beta needs exactly 6 values (Eq 22), got {len(beta)}")
        if not all(math.isfinite(v) for v in (A, n, *beta)):
            raise InvalidInput(f"BoucWenParams must be finite numbers, got A={A}, n={n}, beta={beta}")
        if not n > 0.0:
            raise InvalidInput(f"BoucWenParams.n must be positive (|z|^n in Eq 23), got {n}")
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "beta", beta)

    def as_array(self) -> FloatArray:
        """The eight parameters as a vector in :data:`PARAM_NAMES` order."""
        return np.array([self.A, self.n, *self.beta], dtype=np.float64)

    @classmethod
    def from_array(cls, values: npt.ArrayLike) -> BoucWenParams:
        """Build from a vector ``(A, n, beta1..beta6)``."""
        v = np.asarray(values, dtype=np.float64).ravel()
        if v.size != 8:
            raise InvalidInput(f"a Bouc-Wen parameter vector has 8 entries (A, n, beta1..6), got {v.size}")
        b = v[2:]
        return cls(A=v[0], n=v[1], beta=(b[0], b[1], b[2], b[3], b[4], b[5]))

    @classmethod
    def from_phases(cls, A: float, n: float, psi: npt.ArrayLike) -> BoucWenParams:
        """Build from the six Table 4 phase values ``psi`` via Eq 25."""
        b = betas_from_phases(psi)
        return cls(A=A, n=n, beta=(b[0], b[1], b[2], b[3], b[4], b[5]))

    @property
    def phases(self) -> FloatArray:
        """The Table 4 phase values ``psi_1..psi_6`` (Eq 24)."""
        return phase_values(self.beta)


def phase_values(beta: npt.ArrayLike) -> FloatArray:
    """Eq 24 / Table 4: the shape-function value ``psi_k`` in each of the six phases, from the betas."""
    b = np.asarray(beta, dtype=np.float64)
    if b.shape != (6,):
        raise InvalidInput(f"phase_values needs the 6 betas of Eq 22, got shape {b.shape}")
    return EQ24_PHASE_MATRIX @ b


def betas_from_phases(psi: npt.ArrayLike) -> FloatArray:
    """Eq 25: the six betas from the six Table 4 phase values ``psi_1..psi_6``."""
    p = np.asarray(psi, dtype=np.float64)
    if p.shape != (6,):
        raise InvalidInput(f"betas_from_phases needs the 6 phase values of Table 4, got shape {p.shape}")
    return EQ25_BETA_MATRIX @ p


def phase_of_samples(x_deg: npt.ArrayLike, z_nm: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Table 4 phase (1-6) of each step ``i -> i+1`` of a recursion (length ``len(x) - 1``).

    The phase is set by (sgn x_i, sgn(x_{i+1} - x_i), sgn z_i) as in Eq 23; steps whose sign pattern is
    not one of Table 4's six phases, or where a sign is zero, get phase 0.
    """
    x = np.asarray(x_deg, dtype=np.float64)
    z = np.asarray(z_nm, dtype=np.float64)
    if x.ndim != 1 or x.shape != z.shape:
        raise InvalidInput(
            f"phase_of_samples needs two 1-D arrays of one length, got {x.shape} and {z.shape}"
        )
    sx = np.sign(x[:-1])
    sd = np.sign(np.diff(x))
    sz = np.sign(z[:-1])
    phase = np.zeros(sx.shape, dtype=np.int64)
    for k, (px, pd, pz) in enumerate(_TABLE4_SIGNS, start=1):
        phase[(sx == px) & (sd == pd) & (sz == pz)] = k
    return phase


# --------------------------------------------------------------------------------------------------------
# numba kernels: Eq 23 and its forward sensitivities
# --------------------------------------------------------------------------------------------------------


@njit(cache=True)
def _sgn(v: float) -> float:  # pragma: no cover - compiled
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@njit(cache=True)
def _recursion_kernel(x, seg, z0, A, n, beta, bound, freeze, z):  # pragma: no cover
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
            sd = _sgn(d)
            sx = _sgn(xi)
            sz = _sgn(zi)
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
def _sensitivity_kernel(x, seg, z0, A, n, beta, bound, freeze, z, dz, T):  # pragma: no cover
    """Eq 23 and its exact derivatives ``d z_i / d theta_k``, theta = (A, n, beta1..6), written as
    ``dz[i, :] = (d z_i / d theta) @ T`` (``T`` = identity for the plain derivatives; the fitter passes its
    chain-rule matrix so that no separate pass over the Jacobian is needed).

    Differentiating Eq 23 (the signs are piecewise constant, so their derivative is zero almost
    everywhere) gives, with ``g_i = |z_i|^n`` and ``s_i`` the six signs of Eq 23::

        dz_{i+1} = dz_i + d_i [dA - dg_i Psi_i - g_i (s_i . dbeta)]
        dg_i = n |z_i|^(n-1) sgn(z_i) dz_i + g_i ln|z_i| dn

    At ``z_i = 0`` both terms of ``dg_i`` are taken as 0 (the limit of ``|z|^n ln|z|``; for n < 1 the
    first term has no finite limit and 0 is the one-sided convention).  Divergence handling as in
    :func:`_recursion_kernel`; derivatives after divergence are NaN or 0 (frozen).
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
            sd = _sgn(d)
            sx = _sgn(xi)
            sz = _sgn(zi)
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
            for c in range(8):
                acc = 0.0
                for k in range(8):
                    acc += sens[k] * T[k, c]
                dz[i + 1, c] = acc
    return first_bad


@njit(cache=True)
def _gram(J):  # pragma: no cover
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
def _sum_sq_diff(z, y):  # pragma: no cover
    """``sum((z - y)**2)`` in a plain loop."""
    acc = 0.0
    for i in range(z.size):
        d = z[i] - y[i]
        acc += d * d
    return acc


# --------------------------------------------------------------------------------------------------------
# public simulation
# --------------------------------------------------------------------------------------------------------


_IDENTITY8 = np.eye(8)


def _as_angle(x_deg: npt.ArrayLike, name: str = "x_deg") -> FloatArray:
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
    x, z0f = _as_angle(x_deg), _check_z0(z0)
    z = np.empty_like(x)
    _recursion_kernel(
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
    x, z0f = _as_angle(x_deg), _check_z0(z0)
    z = np.empty_like(x)
    dz = np.empty((x.size, 8))
    _sensitivity_kernel(
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
        _IDENTITY8,
    )
    return z, dz


# --------------------------------------------------------------------------------------------------------
# fitting
# --------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BoucWenBounds:
    """Bounds of the fitted parameters, expressed relative to the data so that they suit any joint.

    With ``X`` the largest |angle| (deg) and ``Z`` the largest |torque| (N*m) of the fitted data, Eq 20
    becomes ``dz'/dx' = a - |z'|^n psi'`` for ``z' = z/Z`` and ``x' = x/X``, with ``a = A X / Z`` and
    ``psi' = psi X Z^(n-1)``.  The bounds are on these dimensionless numbers:

    * ``0 <= a <= a_max`` - ``A >= 0`` makes the torque rise with the angle near ``z = 0`` (a passive joint
      resists the motion); ``a_max = 20`` lets the initial slope be 20 times the loop's mean secant slope
      ``Z/X`` (for X = 65 deg, Z = 20 N*m: A <= 6.2 N*m/deg).
    * ``n_min <= n <= n_max`` (0.5-3): the exponent only shapes the knees of the loop; the thesis fitted
      1.2.
    * ``|psi'_k| <= psi_max`` for the six Table 4 phase values (hence ``|beta'_k| <= psi_max`` too, since
      each row of Eq 25 has four entries of 1/4).  ``psi_max = 100`` allows slopes up to about
      ``dz'/dx' = 100``, i.e. crossing the whole torque range within 1 % of the angle range; the Figure 57
      parameters on a +-65 deg, 20 N*m loop have ``psi'_5 = -57``.  In physical units (X = 65 deg,
      Z = 20 N*m, n = 1.2) this is about ``|psi_k| <= 0.83`` N*m^(1-n)/deg, against 0.47 for Figure 57.

    The fitter also treats |z| > 10 Z as divergence (see :func:`fit`).
    """

    a_max: float = 20.0
    n_min: float = 0.5
    n_max: float = 3.0
    psi_max: float = 100.0

    def __post_init__(self) -> None:
        if not (0.0 < self.a_max < math.inf):
            raise InvalidInput(f"BoucWenBounds.a_max must be positive and finite, got {self.a_max}")
        if not (0.0 < self.n_min < self.n_max < math.inf):
            raise InvalidInput(f"BoucWenBounds needs 0 < n_min < n_max, got {self.n_min}, {self.n_max}")
        if not (0.0 < self.psi_max < math.inf):
            raise InvalidInput(f"BoucWenBounds.psi_max must be positive and finite, got {self.psi_max}")

    def lower(self) -> FloatArray:
        return np.array([0.0, self.n_min, *([-self.psi_max] * 6)])

    def upper(self) -> FloatArray:
        return np.array([self.a_max, self.n_max, *([self.psi_max] * 6)])


DEFAULT_BOUNDS = BoucWenBounds()
FULL_REFIT_R2 = 0.5  # below this on every sample, a decimated fit is redone on every sample (fit_trials)


@dataclass(frozen=True)
class BoucWenFit:
    """Result of :func:`fit` / :func:`fit_trials`.

    params: best-fitting parameters (physical units, see :class:`BoucWenParams`).
    rmse_nm: root-mean-square torque error over every given sample of every trial, with each trial's
        recursion started at its own first torque.
    r2: coefficient of determination over the same samples.
    param_std: 1-sigma uncertainties of (A, n, beta1..6) from the Jacobian at the optimum,
        ``sqrt(diag(s^2 (J^T J)^-1))`` on the fitted samples; ``inf`` for a direction the data cannot
        determine (e.g. a Table 4 phase never visited).  Filtered data has correlated residuals, which makes
        these optimistic.
    n_starts: number of starting points tried; converged: the final local solve met its tolerance;
    diverged: the fitted model's recursion left the data's torque range by a factor 10 on the given samples.
    trial_rmse_nm: RMSE of each trial; n_samples: samples given; n_samples_fitted: samples the optimiser
        used after decimation; stride: decimation step of each trial; nfev: residual evaluations in total.
    angle_scale_deg, torque_scale_nm: the scales X and Z that make :class:`BoucWenBounds` physical.
    message: the final least-squares solver's termination message.
    """

    params: BoucWenParams
    rmse_nm: float
    r2: float
    param_std: FloatArray
    n_starts: int
    converged: bool
    diverged: bool
    trial_rmse_nm: tuple[float, ...]
    n_samples: int
    n_samples_fitted: int
    stride: tuple[int, ...]
    nfev: int
    angle_scale_deg: float
    torque_scale_nm: float
    bounds: BoucWenBounds = field(default=DEFAULT_BOUNDS)
    message: str = ""


_DIVERGENCE_FACTOR = 10.0  # the fitter holds |z| at 10 x the data's torque scale once it diverges
_SCREEN_SAMPLES = 400  # samples per trial of the coarse copy on which every start gets a short solve
_SHORT_NFEV = 6  # residual evaluations of each short solve (stage 1)
_POLISH_NFEV = 200  # limit of the final solve (stage 2)
_TR_SOLVER = "exact"  # least_squares' dense SVD of the Jacobian; cheap for 8 columns


class _Problem:
    """Least-squares problem on concatenated (decimated) trials in the dimensionless parameters
    ``u = (a, n, psi'_1..psi'_6)`` of :class:`BoucWenBounds`; residuals are ``(z - y) / Z``."""

    def __init__(
        self,
        x: FloatArray,
        y: FloatArray,
        seg: npt.NDArray[np.int64],
        bounds: BoucWenBounds,
        angle_scale_deg: float,
        torque_scale_nm: float,
    ):
        self.x = x
        self.y = y
        self.seg = seg
        self.z0 = np.ascontiguousarray(y[seg[:-1]])
        self.X = angle_scale_deg
        self.Z = torque_scale_nm
        self.lnZ = math.log(self.Z)
        self.bound = _DIVERGENCE_FACTOR * self.Z
        self.bounds = bounds
        self.lower = bounds.lower()
        self.upper = bounds.upper()
        self.z = np.empty_like(x)
        self.nfev = 0
        self.diverged_at = -1

    def physical(self, u: FloatArray) -> tuple[float, float, FloatArray]:
        n = float(u[1])
        A = float(u[0]) * self.Z / self.X
        beta = (EQ25_BETA_MATRIX @ u[2:]) / (self.X * self.Z ** (n - 1.0))
        return A, n, beta

    def to_u(self, params: BoucWenParams) -> FloatArray:
        n = params.n
        psi_scaled = phase_values(params.beta) * (self.X * self.Z ** (n - 1.0))
        u = np.array([params.A * self.X / self.Z, n, *psi_scaled])
        return np.clip(u, self.lower, self.upper)

    def params(self, u: FloatArray) -> BoucWenParams:
        A, n, beta = self.physical(u)
        return BoucWenParams(A=A, n=n, beta=(beta[0], beta[1], beta[2], beta[3], beta[4], beta[5]))

    def residuals(self, u: FloatArray) -> FloatArray:
        A, n, beta = self.physical(u)
        self.nfev += 1
        self.diverged_at = _recursion_kernel(self.x, self.seg, self.z0, A, n, beta, self.bound, True, self.z)
        return (self.z - self.y) / self.Z

    def stabilise(self, u: FloatArray) -> FloatArray:
        """Contract a start whose recursion diverges toward the neutral point ``a = 1, psi' = 0`` (a
        straight line of the loop's mean slope, which cannot diverge) by halving the distance until it
        stays within range.  From inside the divergent region no gradient points back out, so without
        this a local solve from such a start stalls on the penalty plateau."""
        centre = u.copy()
        centre[0] = min(max(1.0, self.lower[0]), self.upper[0])
        centre[2:] = 0.0
        v = u.copy()
        for _ in range(60):
            self.residuals(v)
            if self.diverged_at < 0:
                return v
            v = centre + 0.5 * (v - centre)
        return centre

    def cost(self, u: FloatArray) -> float:
        r = self.residuals(u)
        return 0.5 * float(r @ r)

    def physical_jacobian(
        self, A: float, n: float, beta: FloatArray, transform: FloatArray = _IDENTITY8
    ) -> FloatArray:
        """``dz/dtheta @ transform`` on the fitted samples, in a new array (least_squares keeps it)."""
        out = np.empty((self.x.size, 8))
        _sensitivity_kernel(self.x, self.seg, self.z0, A, n, beta, self.bound, True, self.z, out, transform)
        return out

    def jacobian(self, u: FloatArray) -> FloatArray:
        """Chain rule from the physical sensitivities: every column of the dimensionless Jacobian is a
        fixed linear combination of the physical ones, ``J_u = dz/dtheta @ T / Z``."""
        A, n, beta = self.physical(u)
        T = np.zeros((8, 8))
        T[0, 0] = self.Z / self.X  # dA/da
        T[1, 1] = 1.0  # dn/dn
        T[2:, 1] = -self.lnZ * beta  # dbeta/dn at fixed psi' (beta ~ Z^(1-n))
        T[2:, 2:] = EQ25_BETA_MATRIX / (self.X * self.Z ** (n - 1.0))  # dbeta/dpsi'
        return self.physical_jacobian(A, n, beta, T / self.Z)

    def solve(self, u0: FloatArray, max_nfev: int, tol: float) -> tuple[FloatArray, float, bool, str]:
        res = least_squares(
            self.residuals,
            self.stabilise(np.clip(u0, self.lower, self.upper)),
            jac=self.jacobian,
            bounds=(self.lower, self.upper),
            x_scale="jac",
            method="trf",
            tr_solver=_TR_SOLVER,
            ftol=tol,
            xtol=tol,
            gtol=tol,
            max_nfev=max_nfev,
        )
        return np.asarray(res.x, dtype=np.float64), float(res.cost), bool(res.status > 0), str(res.message)


def _thesis_start(x: FloatArray, y: FloatArray, seg: npt.NDArray[np.int64]) -> BoucWenParams:
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


def _equation_error_start(
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


def _validate_segments(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
) -> list[tuple[FloatArray, FloatArray]]:
    if len(segments) == 0:
        raise InvalidInput("no trials to fit: give at least one (angle_deg, torque_nm) segment")
    out: list[tuple[FloatArray, FloatArray]] = []
    for k, seg in enumerate(segments):
        try:
            xa, ya = seg
        except (TypeError, ValueError):
            raise InvalidInput(f"trial {k} must be a pair (angle_deg, torque_nm)") from None
        x = _as_angle(xa, f"trial {k} angle")
        y = _as_angle(ya, f"trial {k} torque")
        if x.size != y.size:
            raise InvalidInput(f"trial {k}: {x.size} angle samples but {y.size} torque samples")
        if x.size < 3:
            raise InvalidInput(f"trial {k} has {x.size} samples; the recursion needs at least 3")
        out.append((x, y))
    if all(np.ptp(x) == 0.0 for x, _ in out):
        raise InvalidInput("the angle never changes: a hysteresis model cannot be fitted to a static joint")
    if all(np.max(np.abs(y)) == 0.0 for _, y in out):
        raise InvalidInput("the torque is zero everywhere: there is no hysteresis to fit")
    if all(np.max(np.abs(x)) == 0.0 for x, _ in out):
        raise InvalidInput("the angle is zero everywhere")
    return out


def _decimate(
    segments: list[tuple[FloatArray, FloatArray]], max_samples_per_trial: int | None
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64], tuple[int, ...]]:
    xs: list[FloatArray] = []
    ys: list[FloatArray] = []
    strides: list[int] = []
    for x, y in segments:
        stride = 1 if max_samples_per_trial is None else max(1, math.ceil(x.size / max_samples_per_trial))
        xs.append(x[::stride])
        ys.append(y[::stride])
        strides.append(stride)
    seg = np.zeros(len(xs) + 1, dtype=np.int64)
    seg[1:] = np.cumsum([len(v) for v in xs])
    return np.concatenate(xs), np.concatenate(ys), seg, tuple(strides)


def _param_std(problem: _Problem, params: BoucWenParams) -> FloatArray:
    """``sqrt(diag(s^2 (J^T J)^-1))`` with the physical Jacobian on the fitted samples; ``inf`` for a
    parameter that has no effect or mixes with a (numerically) unidentifiable direction.

    ``J^T J`` is formed with its columns scaled to unit norm and inverted on the subspace whose
    eigenvalues exceed 1e-12 of the largest (singular values 1e-6 of the largest)."""
    dz = problem.physical_jacobian(params.A, params.n, np.array(params.beta))
    m = problem.y.size
    std = np.full(8, np.inf)
    if m <= 8 or not np.all(np.isfinite(dz)):
        return std
    s2 = float(_sum_sq_diff(problem.z, problem.y)) / (m - 8)
    G = _gram(dz)
    norm = np.sqrt(np.diag(G))
    active = norm > 0.0
    if not np.any(active):
        return std
    Gs = G[np.ix_(active, active)] / np.outer(norm[active], norm[active])
    eigval, eigvec = np.linalg.eigh(Gs)
    good = eigval > eigval[-1] * 1e-12
    cov_s = (eigvec[:, good] / eigval[good]) @ eigvec[:, good].T
    std_active = np.sqrt(np.clip(np.diag(cov_s), 0.0, None) * s2) / norm[active]
    null = eigvec[:, ~good]
    if null.size:
        std_active[np.any(np.abs(null) > 1e-8, axis=1)] = np.inf
    std[active] = std_active
    return std


def _evaluate(
    segments: list[tuple[FloatArray, FloatArray]], params: BoucWenParams, bound: float
) -> tuple[float, float, tuple[float, ...], bool]:
    """RMSE, R^2, per-trial RMSE and divergence flag of ``params`` on every given sample, each trial's
    recursion started at its own first torque (diverged samples held at +-bound, a finite error)."""
    beta = np.array(params.beta)
    sse: list[float] = []
    total = 0.0
    total_sq = 0.0
    count = 0
    diverged = False
    for x, y in segments:
        z = np.empty_like(x)
        bad = _recursion_kernel(
            x, np.array([0, x.size], dtype=np.int64), y[:1].copy(), params.A, params.n, beta, bound, True, z
        )
        diverged = diverged or bad >= 0
        sse.append(float(_sum_sq_diff(z, y)))
        total += float(np.sum(y))
        total_sq += float(np.sum(np.square(y)))
        count += y.size
    rmse = math.sqrt(sum(sse) / count)
    sst = total_sq - total * total / count
    r2 = 1.0 - sum(sse) / sst if sst > 0.0 else math.nan
    per = tuple(math.sqrt(e / x.size) for e, (x, _) in zip(sse, segments, strict=True))
    return rmse, r2, per, diverged


def _diverges_when_decimated(u: FloatArray, screen: _Problem, problem: _Problem) -> bool:
    """True when the recursion with parameters `u` stays bounded on the coarse screening copy but diverges
    on the (finer) fitted samples."""
    screen.residuals(u)
    screen.nfev -= 1  # checks, not steps of a solve
    if screen.diverged_at >= 0:
        return False
    problem.residuals(u)
    problem.nfev -= 1
    return problem.diverged_at >= 0


def _fit_segments(
    segments: list[tuple[FloatArray, FloatArray]],
    *,
    starts: int,
    initial: BoucWenParams | Sequence[BoucWenParams] | None,
    data_starts: bool,
    bounds: BoucWenBounds,
    seed: int,
    max_samples_per_trial: int | None,
    polish: int,
    polish_tol: float = 1e-10,
) -> BoucWenFit:
    if starts < 0:
        raise InvalidInput(f"starts must be >= 0, got {starts}")
    if max_samples_per_trial is not None and max_samples_per_trial < 3:
        raise InvalidInput(f"max_samples_per_trial must be at least 3, got {max_samples_per_trial}")
    angle_scale = max(float(np.max(np.abs(x))) for x, _ in segments)
    torque_scale = max(float(np.max(np.abs(y))) for _, y in segments)
    x, y, seg, strides = _decimate(segments, max_samples_per_trial)
    problem = _Problem(x, y, seg, bounds, angle_scale, torque_scale)
    screen_samples = (
        _SCREEN_SAMPLES if max_samples_per_trial is None else min(_SCREEN_SAMPLES, max_samples_per_trial)
    )
    xs, ys, segs, screen_strides = _decimate(segments, screen_samples)
    screen = (
        problem if screen_strides == strides else _Problem(xs, ys, segs, bounds, angle_scale, torque_scale)
    )

    candidates: list[FloatArray] = []
    if initial is not None:
        for p in [initial] if isinstance(initial, BoucWenParams) else list(initial):
            candidates.append(problem.to_u(p))
    if data_starts:
        candidates.append(problem.to_u(_thesis_start(xs, ys, segs)))
        ee = _equation_error_start(xs, ys, segs, np.linspace(bounds.n_min, bounds.n_max, 11))
        if ee is not None:
            candidates.append(problem.to_u(ee))
    if starts > 0:
        unit = qmc.Halton(d=8, scramble=True, rng=seed).random(starts)
        candidates.extend(problem.lower + unit[k] * (problem.upper - problem.lower) for k in range(starts))
    if not candidates:
        raise InvalidInput("no starting point: give starts > 0, data_starts=True or an initial guess")

    # Stage 1: a short solve from every start on a coarse copy of the data picks the basin.
    short = []
    for u0 in candidates:
        u, cost, _, _ = screen.solve(u0, max_nfev=_SHORT_NFEV, tol=1e-6)
        short.append((cost, u))
    short.sort(key=lambda t: t[0])
    if (
        problem is not screen
        and any(s > 1 for s in strides)
        and _diverges_when_decimated(short[0][1], screen, problem)
    ):
        # The best start is stable on the coarse copy but its recursion diverges on the decimated samples:
        # explicit-Euler steps of the decimated data misbehave for this loop (a range-of-motion stop makes
        # it nearly vertical), so a fit there would not carry over to every sample. Polish on every
        # sample instead (fit_trials' guard would otherwise redo it there, after a wasted decimated fit).
        x, y, seg, strides = _decimate(segments, None)
        problem = _Problem(x, y, seg, bounds, angle_scale, torque_scale)
    # Stage 2: the best few are refined to convergence on the fitted samples; the lowest cost wins.
    # A short solve that ended at the cost of one already chosen (within 0.1 %: the same valley) or
    # clearly above the best (by 5 %) is not polished.
    chosen: list[FloatArray] = []
    chosen_cost: list[float] = []
    for cost0, u0 in short:
        if len(chosen) >= max(1, polish) or cost0 > 1.05 * short[0][0]:
            break
        if all(abs(cost0 - c) > 1e-3 * c for c in chosen_cost):
            chosen.append(u0)
            chosen_cost.append(cost0)
    best: tuple[float, FloatArray, bool, str] | None = None
    for u0 in chosen:
        u, cost, ok, message = problem.solve(u0, max_nfev=_POLISH_NFEV, tol=polish_tol)
        if best is None or cost < best[0]:
            best = (cost, u, ok, message)
    assert best is not None
    params = problem.params(best[1])
    std = _param_std(problem, params)
    rmse, r2, per, diverged = _evaluate(segments, params, problem.bound)
    return BoucWenFit(
        params=params,
        rmse_nm=rmse,
        r2=r2,
        param_std=std,
        n_starts=len(candidates),
        converged=best[2],
        diverged=diverged,
        trial_rmse_nm=per,
        n_samples=sum(s[0].size for s in segments),
        n_samples_fitted=int(x.size),
        stride=strides,
        nfev=problem.nfev + (screen.nfev if screen is not problem else 0),
        angle_scale_deg=angle_scale,
        torque_scale_nm=torque_scale,
        bounds=bounds,
        message=best[3],
    )


def fit(
    x_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    trials: Sequence[int] | None = None,
    starts: int = 4,
    initial: BoucWenParams | Sequence[BoucWenParams] | None = None,
    data_starts: bool = True,
    bounds: BoucWenBounds = DEFAULT_BOUNDS,
    seed: int = 0,
    max_samples_per_trial: int | None = 8000,
    polish: int = 1,
) -> BoucWenFit:
    """Fit the generalised Bouc-Wen model (Eq 23) to angle/torque samples by least squares (§6.2.3).

    The samples are fitted as given - no centring here (the thesis centres each trial on (0, 0) first,
    note under Table 4; do that before calling).  The recursion starts at ``z0 = torque_nm[0]``.

    trials: lengths of consecutive trials making up ``x_deg``/``torque_nm`` (they must sum to its length);
        each trial restarts the recursion at its own first torque, so concatenation adds no fake jump.
        ``None`` means one trial.  :func:`fit_trials` takes a list of segments instead.
    starts: number of quasi-random (scrambled Halton, seeded by ``seed``) starting points spread over
        ``bounds``, in addition to the data-driven ones.
    initial: extra starting point(s) of your own.
    data_starts: include the thesis's Figure 56 start (A = 1, n = 1, per-phase typical Psi through Eq 25)
        and an equation-error least-squares start.
    bounds: see :class:`BoucWenBounds` (relative to the data's angle and torque scales).
    max_samples_per_trial: each trial longer than this is decimated by a uniform stride before fitting
        (``None``: never).  Eq 23 depends only on the angle increments, so this is valid for smooth
        (already filtered) data, but the explicit-Euler error grows with the angle step, so do not decimate
        raw, noisy data.  RMSE and R^2 are always reported on every given sample.  Cost of the default:
        on three 65 s trials at 1 kHz (stride 9) the RMSE was 0.2033 N*m against 0.2005 N*m when fitting
        every sample, in about a tenth of the time (``benchmarks/bench_bouc_wen.py --full``).
    polish: how many of the best short fits are refined to full convergence.

    Procedure: every start gets a short trust-region solve (``scipy.optimize.least_squares``, analytic
    Jacobian, bounds) on a coarse copy of the data (at most 400 samples per trial); the best ``polish``
    distinct ones are refined on the fitted samples and the lowest cost wins.  If the best start's recursion
    stays bounded on the coarse copy but diverges on the decimated samples (explicit-Euler steps too long
    for the loop: range-of-motion stops), the refinement runs on every sample instead.  A start whose
    recursion diverges is first pulled toward a straight line of the loop's mean slope until it no longer
    does.  Unstable parameter sets met during the solve are not errors: the simulated torque is held at
    10x the data's torque scale from the divergence on, a large finite penalty.
    """
    x = _as_angle(x_deg)
    y = _as_angle(torque_nm, "torque_nm")
    if x.size != y.size:
        raise InvalidInput(f"{x.size} angle samples but {y.size} torque samples")
    if trials is None:
        lengths = [x.size]
    else:
        lengths = [int(v) for v in trials]
        if any(v <= 0 for v in lengths) or sum(lengths) != x.size:
            raise InvalidInput(
                f"trials must be positive lengths summing to the {x.size} samples, got {list(trials)}"
            )
    edges = np.concatenate([[0], np.cumsum(lengths)])
    segments = [(x[edges[k] : edges[k + 1]], y[edges[k] : edges[k + 1]]) for k in range(len(lengths))]
    return fit_trials(
        segments,
        starts=starts,
        initial=initial,
        data_starts=data_starts,
        bounds=bounds,
        seed=seed,
        max_samples_per_trial=max_samples_per_trial,
        polish=polish,
    )


def fit_trials(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    starts: int = 4,
    initial: BoucWenParams | Sequence[BoucWenParams] | None = None,
    data_starts: bool = True,
    bounds: BoucWenBounds = DEFAULT_BOUNDS,
    seed: int = 0,
    max_samples_per_trial: int | None = 8000,
    polish: int = 1,
) -> BoucWenFit:
    """Fit one model jointly to several trials ``[(angle_deg, torque_nm), ...]`` of one configuration.

    Each trial starts its own Eq 23 recursion at its own first torque.  Options as in :func:`fit`.

    Decimation guard: a loop on which the best start already diverges when decimated is polished on every
    sample from the start (see :func:`fit`).  Where a fit on decimated samples does not carry over to every
    sample (R^2 below FULL_REFIT_R2 or divergence, e.g. a range-of-motion stop that makes the loop nearly
    vertical, where explicit Euler steps of a few degrees misbehave), the fit is redone on every sample and
    the better of the two (by RMSE on every sample) is returned.
    """
    checked = _validate_segments(segments)
    result = _fit_segments(
        checked,
        starts=starts,
        initial=initial,
        data_starts=data_starts,
        bounds=bounds,
        seed=seed,
        max_samples_per_trial=max_samples_per_trial,
        polish=polish,
    )
    decimated = any(s > 1 for s in result.stride)
    if decimated and (result.diverged or not result.r2 >= FULL_REFIT_R2):
        full = _fit_segments(
            checked,
            starts=0,
            initial=result.params,
            data_starts=False,
            bounds=bounds,
            seed=seed,
            max_samples_per_trial=None,
            polish=1,
        )
        if full.rmse_nm < result.rmse_nm:
            return full
    return result


def cross_validate(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    starts: int = 4,
    bounds: BoucWenBounds = DEFAULT_BOUNDS,
    seed: int = 0,
    max_samples_per_trial: int | None = 8000,
    initial: BoucWenParams | None = None,
) -> list[float]:
    """Leave-one-trial-out RMSE (N*m): for each trial, fit the others with :func:`fit_trials` and predict
    the held-out trial from its own first torque (Eq 23).  Needs at least two trials.

    initial: warm start (e.g. the fit on all trials). Each held-out fit then starts from it alone instead
        of the multi-start search: the same optimum for well-posed data, at a fraction of the cost.
    """
    checked = _validate_segments(segments)
    if len(checked) < 2:
        raise InvalidInput(f"cross-validation needs at least 2 trials, got {len(checked)}")
    errors: list[float] = []
    for k, (x, y) in enumerate(checked):
        others = [s for j, s in enumerate(checked) if j != k]
        result = _fit_segments(
            others,
            starts=starts if initial is None else 0,
            initial=initial,
            data_starts=initial is None,
            bounds=bounds,
            seed=seed,
            max_samples_per_trial=max_samples_per_trial,
            polish=1,
            # from a warm start the held-out error settles long before a tight tolerance is met
            polish_tol=1e-10 if initial is None else 1e-6,
        )
        scale = max(float(np.max(np.abs(y))), max(float(np.max(np.abs(yy))) for _, yy in others))
        rmse, _, _, _ = _evaluate([(x, y)], result.params, _DIVERGENCE_FACTOR * scale)
        errors.append(rmse)
    return errors
