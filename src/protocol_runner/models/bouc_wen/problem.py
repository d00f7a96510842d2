"""The least-squares problem of the Bouc-Wen fit: residuals, Jacobian, uncertainties and evaluation on
every sample (thesis §6.2.3, Figure 56); its bounds and the fit record are in :mod:`.records`."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from .kernels import IDENTITY8, gram, sum_sq_diff
from .params import EQ25_BETA_MATRIX, BoucWenParams, FloatArray, phase_values
from .records import BoucWenBounds
from .schemes import (
    REFINED,
    BoucWenShape,
    Integration,
    Sensitivity,
    check_scheme,
    run_scheme,
    run_trials,
)
from .simulation import refine_angle

REFINE_FACTOR = 4  # rmse_refined_nm: this many times finer integration


DIVERGENCE_FACTOR = 10.0  # the fitter holds |z| at 10 x the data's torque scale once it diverges
_SCREEN_SAMPLES = 400  # samples per trial of the coarse copy on which every start gets a short solve
_SHORT_NFEV = 6  # residual evaluations of each short solve (stage 1)
_POLISH_NFEV = 200  # limit of the final solve (stage 2)
_TR_SOLVER = "exact"  # least_squares' dense SVD of the Jacobian; cheap for 8 columns


class Samples(NamedTuple):
    """The fitted data: concatenated trials' angle ``x`` (deg) and torque ``y`` (N*m), the segment starts
    ``seg`` (one more than the trials; each trial's state restarts at its first torque) and the samples
    compared with the data, ``rows`` (increasing; all when None)."""

    x: FloatArray
    y: FloatArray
    seg: npt.NDArray[np.int64]
    rows: npt.NDArray[np.int64] | None = None


class FitScale(NamedTuple):
    """The data's largest |angle| (deg) and |torque| (N*m): the units of the dimensionless parameters."""

    angle_deg: float
    torque_nm: float


class Problem:
    """Least-squares problem on concatenated (decimated) trials in the dimensionless parameters
    ``u = (a, n, psi'_1..psi'_6)`` of :class:`BoucWenBounds`; residuals are ``(z - y) / Z``."""

    def __init__(
        self,
        samples: Samples,
        bounds: BoucWenBounds,
        scale: FitScale,
        scheme: str = REFINED,
        max_step_deg: float | None = None,
    ):
        x, y, seg, rows = samples
        angle_scale_deg, torque_scale_nm = scale
        # rows: the samples compared with the data (all when None); the state is integrated along every
        # sample of x, so dropping residuals (decimation) never changes the angle path the model follows
        self.rows = rows
        self.y_rows = y if rows is None else np.ascontiguousarray(y[rows])
        self.x = x
        self.y = y
        self.seg = seg
        self.z0 = np.ascontiguousarray(y[seg[:-1]])
        self.X = angle_scale_deg
        self.Z = torque_scale_nm
        self.lnZ = math.log(self.Z)
        self.bound = DIVERGENCE_FACTOR * self.Z
        self.integration = Integration(scheme, self.bound, True, max_step_deg)
        self._check = self.integration._replace(stop_at_divergence=True)  # while checking (diverges())
        self._checking = False
        self.bounds = bounds
        self.lower = bounds.lower()
        self.upper = bounds.upper()
        self.z = np.empty_like(x)
        self.nfev = 0
        self.diverged_at = -1
        # During a solve every residual evaluation also computes the Jacobian (the same torque bit for bit,
        # at 1.5 times the work), which the solver asks for at the point it has just evaluated.
        self.fused = False
        self._cached: tuple[FloatArray, FloatArray, FloatArray] | None = None  # u, Jacobian, residuals

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
        return self._residuals_of(u, self._evaluate(u))

    def diverges(self, u: FloatArray) -> bool:
        """One check of ``u`` (an evaluation, counted): whether the recursion diverges.  The integration
        stops at the first diverged sample, so a check that diverges leaves the torque (and the Jacobian)
        incomplete and keeps nothing; one that stays bounded is a whole evaluation, the very one
        :meth:`residuals` makes (when ``fused``, the solver's cached first evaluation if it starts there)."""
        self._cached = None
        self._checking = True
        try:
            J = self._evaluate(u)
        finally:
            self._checking = False
        if self.diverged_at >= 0:
            return True
        if J is not None:
            self._residuals_of(u, J)
        return False

    def _evaluate(self, u: FloatArray) -> FloatArray | None:
        """The torque at ``u`` into ``self.z`` (and ``diverged_at``); when ``fused`` also the Jacobian,
        returned."""
        A, n, beta = self.physical(u)
        self.nfev += 1
        if not self.fused:
            self.diverged_at = self._integrate(A, n, beta)
            return None
        J, self.diverged_at = self._sensitivity(A, n, beta, self._chain(n, beta) / self.Z)
        return J

    def _residuals_of(self, u: FloatArray, J: FloatArray | None) -> FloatArray:
        """The residuals of the torque just integrated at ``u``; with its Jacobian ``J`` (a fused
        evaluation) both are kept for the solver."""
        z = self.z if self.rows is None else self.z[self.rows]
        r = (z - self.y_rows) / self.Z
        self._cached = None if J is None else (u.copy(), J, r)
        return r

    def _solver_residuals(self, u: FloatArray) -> FloatArray:
        """:meth:`residuals` for the solver: the last fused evaluation's when it was at ``u`` (the start,
        which :meth:`stabilise` has just checked), else a new one."""
        if self._cached is not None and np.array_equal(self._cached[0], u):
            return self._cached[2]
        return self.residuals(u)

    def stabilise(self, u: FloatArray) -> FloatArray:
        """Contract a start whose recursion diverges toward the neutral point ``a = 1, psi' = 0`` (a
        straight line of the loop's mean slope, which cannot diverge) by halving the distance until it
        stays within range: from inside the divergent region no gradient points back out.  Inside a solve
        (``fused``) the check that passes is the solver's first evaluation."""
        centre = u.copy()
        centre[0] = min(max(1.0, self.lower[0]), self.upper[0])
        centre[2:] = 0.0
        v = u.copy()
        for _ in range(60):
            if not self.diverges(v):
                return v
            v = centre + 0.5 * (v - centre)
        return centre

    def cost(self, u: FloatArray) -> float:
        r = self.residuals(u)
        return 0.5 * float(r @ r)

    def physical_jacobian(
        self, A: float, n: float, beta: FloatArray, transform: FloatArray = IDENTITY8
    ) -> FloatArray:
        """``dz/dtheta @ transform`` on the fitted samples, in a new array (least_squares keeps it); the
        torque into ``self.z`` and ``diverged_at``, as an evaluation."""
        dz, self.diverged_at = self._sensitivity(A, n, beta, transform)
        return dz

    def _sensitivity(
        self, A: float, n: float, beta: FloatArray, transform: FloatArray
    ) -> tuple[FloatArray, int]:
        """The torque into ``self.z`` and ``dz/dtheta @ transform`` at the compared rows (a new array);
        the index of the first diverged sample or -1."""
        out = np.empty((self.x.size if self.rows is None else self.rows.size, 8))
        return out, self._integrate(A, n, beta, out, transform)

    def _integrate(
        self, A: float, n: float, beta: FloatArray, dz: FloatArray | None = None, T: FloatArray = IDENTITY8
    ) -> int:
        """The torque into ``self.z`` (divergence frozen at the bound, or stopping there in a check), with
        ``dz`` also ``dz/dtheta @ T`` at the compared rows; the index of the first diverged sample or -1."""
        sensitivity = None if dz is None else Sensitivity(dz, T, self.rows)
        how = self._check if self._checking else self.integration
        return run_scheme(self.x, self.seg, self.z0, BoucWenShape(A, n, beta), how, self.z, sensitivity)

    def _chain(self, n: float, beta: FloatArray) -> FloatArray:
        """``d theta / d u``: every column of the dimensionless Jacobian is a fixed linear combination of
        the physical sensitivities."""
        T = np.zeros((8, 8))
        T[0, 0] = self.Z / self.X  # dA/da
        T[1, 1] = 1.0  # dn/dn
        T[2:, 1] = -self.lnZ * beta  # dbeta/dn at fixed psi' (beta ~ Z^(1-n))
        T[2:, 2:] = EQ25_BETA_MATRIX / (self.X * self.Z ** (n - 1.0))  # dbeta/dpsi'
        return T

    def jacobian(self, u: FloatArray) -> FloatArray:
        """Chain rule from the physical sensitivities, ``J_u = dz/dtheta @ T / Z``; taken from the last
        residual evaluation when that was fused and at the same point."""
        if self._cached is not None and np.array_equal(self._cached[0], u):
            return self._cached[1]
        A, n, beta = self.physical(u)
        return self.physical_jacobian(A, n, beta, self._chain(n, beta) / self.Z)

    def rmse(self, cost: float) -> float:
        """RMSE in N*m of a cost of this problem."""
        return math.sqrt(2.0 * cost / self.y_rows.size) * self.Z

    def solve(
        self, u0: FloatArray, max_nfev: int, tol: float, ftol: float | None = None
    ) -> tuple[FloatArray, float, int, str]:
        """Bounded trust-region solve from ``u0``; ``ftol`` (default ``tol``) is the relative decrease of
        the cost below which a step ends it, ``tol`` the step and gradient tolerances."""
        self.fused = True
        try:
            start = self.stabilise(np.clip(u0, self.lower, self.upper))
            res = least_squares(
                self._solver_residuals,
                start,
                jac=self.jacobian,
                bounds=(self.lower, self.upper),
                x_scale="jac",
                method="trf",
                tr_solver=_TR_SOLVER,
                ftol=tol if ftol is None else ftol,
                xtol=tol,
                gtol=tol,
                max_nfev=max_nfev,
            )
        finally:
            self.fused = False
            self._cached = None
        return np.asarray(res.x, dtype=np.float64), float(res.cost), int(res.status), str(res.message)


def param_std(problem: Problem, params: BoucWenParams) -> FloatArray:
    """``sqrt(diag(s^2 (J^T J)^-1))`` with the physical Jacobian on the fitted samples; ``inf`` for a
    parameter that has no effect or mixes with a (numerically) unidentifiable direction.

    ``J^T J`` is formed with its columns scaled to unit norm and inverted on the subspace whose
    eigenvalues exceed 1e-12 of the largest (singular values 1e-6 of the largest)."""
    dz = problem.physical_jacobian(params.A, params.n, np.array(params.beta))
    z = problem.z if problem.rows is None else np.ascontiguousarray(problem.z[problem.rows])
    return jacobian_std(dz, float(sum_sq_diff(z, problem.y_rows)))


def jacobian_std(J: FloatArray, sse: float) -> FloatArray:
    """``sqrt(diag(s^2 (J^T J)^-1))``, ``s^2 = sse / (m - 8)``, for any parametrisation's Jacobian ``J``
    (m x 8); ``inf`` as in :func:`param_std`."""
    m = J.shape[0]
    std = np.full(8, np.inf)
    if m <= 8 or not np.all(np.isfinite(J)):
        return std
    s2 = sse / (m - 8)
    G = gram(np.ascontiguousarray(J))
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


def evaluate(
    segments: list[tuple[FloatArray, FloatArray]],
    params: BoucWenParams,
    bound: float,
    scheme: str = REFINED,
    max_step_deg: float | None = None,
) -> tuple[float, float, tuple[float, ...], bool]:
    """RMSE, R^2, per-trial RMSE and divergence flag of ``params`` on every given sample, each trial's
    recursion started at its own first torque (diverged samples held at +-bound, a finite error)."""
    integration = Integration(scheme, bound, True, max_step_deg)
    torques, bad = run_trials(
        [x for x, _ in segments], params, [float(y[0]) for _, y in segments], integration
    )
    return scores(segments, torques, bad >= 0)


def trial_torques(
    problem: Problem, segments: list[tuple[FloatArray, FloatArray]], scheme: str
) -> list[FloatArray] | None:
    """Each trial's torque from the problem's last integration when that integrated exactly these trials,
    every sample, as :func:`evaluate` does with ``scheme`` and the problem's bound (the same substeps,
    each trial from its own first torque): then the very torque of :func:`evaluate`, bit for bit; None
    when the problem is another copy of the trials."""
    if problem.integration != Integration(scheme, problem.bound) or problem.seg.size != len(segments) + 1:
        return None
    torques: list[FloatArray] = []
    for k, (x, y) in enumerate(segments):
        a, b = int(problem.seg[k]), int(problem.seg[k + 1])
        if not (np.array_equal(problem.x[a:b], x) and problem.z0[k] == y[0]):
            return None
        torques.append(problem.z[a:b])
    return torques


def scores(
    segments: list[tuple[FloatArray, FloatArray]], torques: list[FloatArray], diverged: bool
) -> tuple[float, float, tuple[float, ...], bool]:
    """What :func:`evaluate` returns, from each trial's model torque at every sample and whether any
    diverged."""
    sse: list[float] = []
    total = 0.0
    total_sq = 0.0
    count = 0
    for z, (_, y) in zip(torques, segments, strict=True):
        sse.append(float(sum_sq_diff(z, y)))
        total += float(np.sum(y))
        total_sq += float(np.sum(np.square(y)))
        count += y.size
    rmse = math.sqrt(sum(sse) / count)
    sst = total_sq - total * total / count
    r2 = 1.0 - sum(sse) / sst if sst > 0.0 else math.nan
    per = tuple(math.sqrt(e / x.size) for e, (x, _) in zip(sse, segments, strict=True))
    return rmse, r2, per, diverged


def refined_rmse(
    segments: list[tuple[FloatArray, FloatArray]], params: BoucWenParams, bound: float, scheme: str = REFINED
) -> float:
    """RMSE of ``params`` with 4x finer integration: each trial's angle samples interpolated 4x finer (the
    same piecewise-linear path), substeps 4x shorter, the torque compared at the given samples."""
    step = check_scheme(scheme, None) / REFINE_FACTOR
    sse = 0.0
    count = 0
    integration = Integration(scheme, bound, True, step)
    fine = [refine_angle(x, REFINE_FACTOR) for x, _ in segments]
    torques, _ = run_trials(fine, params, [float(y[0]) for _, y in segments], integration)
    for z, (_, y) in zip(torques, segments, strict=True):
        sse += float(sum_sq_diff(np.ascontiguousarray(z[::REFINE_FACTOR]), y))
        count += y.size
    return math.sqrt(sse / count)
