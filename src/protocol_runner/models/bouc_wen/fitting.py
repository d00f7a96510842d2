"""Fitting the generalised Bouc-Wen model to trials by multi-start least squares (thesis §6.2.3,
Figure 56): the options, the data-driven starts, the multi-start solve and leave-one-trial-out
cross-validation (the trial is the unit)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple, ParamSpec, TypedDict, TypeVar, Unpack

import numpy as np
import numpy.typing as npt
from scipy.stats import qmc
from threadpoolctl import ThreadpoolController

from protocol_runner.errors import InvalidInput

from .backbone import AnyBackbone, BackboneFactory, fit_backbone, hysteretic_part
from .copies import _path_problem, decimate, turning_point_copy
from .params import BoucWenParams, FloatArray, phase_of_samples
from .problem import (
    _POLISH_NFEV,
    _SCREEN_SAMPLES,
    _SHORT_NFEV,
    DIVERGENCE_FACTOR,
    FitScale,
    Problem,
    Samples,
    evaluate,
    param_std,
    refined_rmse,
    scores,
    trial_torques,
)
from .records import DEFAULT_BOUNDS, FULL_REFIT_R2, BoucWenBounds, BoucWenFit
from .schemes import EQ23, REFINED, check_scheme
from .simulation import as_angle

P = ParamSpec("P")
R = TypeVar("R")
_controller: ThreadpoolController | None = None


def blas_single_threaded(fn: Callable[P, R]) -> Callable[P, R]:
    """Run ``fn`` with every loaded BLAS at one thread, the caller's limits restored after: the solver's
    linear algebra on tall 8-column Jacobians is too little work per call to share between threads.  The
    one threadpoolctl controller per process is made at the first fit, once numpy and scipy have loaded
    their BLAS (environment variables such as ``OPENBLAS_NUM_THREADS`` act only when a library loads)."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        global _controller
        if _controller is None:
            _controller = ThreadpoolController()
        with _controller.limit(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper


class FitKeywords(TypedDict, total=False):
    """The keywords of :func:`.fit`, :func:`.fit_trials` and :func:`.cross_validate` (meaning and defaults:
    :class:`FitOptions`)."""

    starts: int
    initial: BoucWenParams | Sequence[BoucWenParams] | None
    data_starts: bool
    bounds: BoucWenBounds
    seed: int
    max_samples_per_trial: int | None
    polish: int
    scheme: str


POLISH_FTOL = 1e-5  # the polish on the mid-size copy ends at this relative cost decrease (docs/analysis.md)


@dataclass(frozen=True)
class FitOptions:
    """How one multi-start fit runs (see :func:`.fit` for the procedure).

    starts: quasi-random (scrambled Halton, seeded by ``seed``) starting points spread over ``bounds``, in
        addition to the data-driven ones.
    initial: extra starting point(s) of your own.
    data_starts: include the thesis's Figure 56 start (A = 1, n = 1, per-phase typical Psi through Eq 25)
        and an equation-error least-squares start.
    bounds: see :class:`.BoucWenBounds` (relative to the data's angle and torque scales).
    max_samples_per_trial: each trial longer than this is decimated by a uniform stride before fitting
        (``None``: never).
    polish: how many of the best short fits are refined to full convergence.
    scheme: ``"refined"`` (step-independent) or ``"eq23"`` (the thesis's literal recursion).
    polish_tol: step and gradient tolerance of the refinement.
    polish_ftol: relative cost decrease that ends the polish on the mid-size copy (``None``: ``polish_tol``).
    final_solve: False ends the refined scheme's fit with the polish on a mid-size copy that keeps the
        angle's turning points (:func:`.copies.turning_point_copy`) instead of a last solve on the fitted
        samples (the held-out fits of :func:`.cross_validate`).
    """

    starts: int = 4
    initial: BoucWenParams | Sequence[BoucWenParams] | None = None
    data_starts: bool = True
    bounds: BoucWenBounds = DEFAULT_BOUNDS
    seed: int = 0
    max_samples_per_trial: int | None = 8000
    polish: int = 1
    scheme: str = REFINED
    polish_tol: float = 1e-10
    polish_ftol: float | None = POLISH_FTOL
    final_solve: bool = True


_MID_SAMPLES = 1500  # samples per trial of the copy on which the refined scheme's polish starts
_FINAL_NFEV = 40  # then at most this many residual evaluations on the fitted samples,
_FINAL_TOL = 1e-8  # to this step and gradient tolerance (the copy's optimum is close),
FINAL_FTOL = 1e-5  # ending once a step lowers the cost by less than this fraction (early stopping)
MID_STEP_DEG = 0.25  # substep of the refined integration on that copy (the final solve uses the default)
SCREEN_STEP_DEG = 0.5  # substep of the refined integration while screening starts (only picks the basin)


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
        x = as_angle(xa, f"trial {k} angle")
        y = as_angle(ya, f"trial {k} torque")
        if x.size != y.size:
            raise InvalidInput(f"trial {k}: {x.size} angle samples but {y.size} torque samples")
        if x.size < 3:
            raise InvalidInput(f"trial {k} has {x.size} samples; the recursion needs at least 3")
        out.append((x, y))
    if all(np.ptp(x) == 0.0 for x, _ in out):
        raise InvalidInput("the angle never changes: a hysteresis model cannot be fitted to a static joint")
    if all(np.max(np.abs(y)) == 0.0 for _, y in out):
        raise InvalidInput("the torque is zero everywhere: there is no hysteresis to fit")
    return out


def backbone_for(
    segments: list[tuple[FloatArray, FloatArray]],
    indices: Sequence[int],
    degree: int | None,
    factory: BackboneFactory | None,
) -> AnyBackbone | None:
    """The backbone ``g`` of a fit on ``segments`` (the trials ``indices`` of the configuration): a
    polynomial of ``degree`` fitted to them, the ``factory``'s for those trials, or None (``torque = z``)."""
    if degree is not None and factory is not None:
        raise InvalidInput("give a backbone degree or a backbone factory, not both")
    if degree is not None:
        return fit_backbone(segments, degree)
    return None if factory is None else factory(indices)


def _trials(
    x: FloatArray, y: FloatArray, seg: npt.NDArray[np.int64]
) -> Iterator[tuple[FloatArray, FloatArray]]:
    """Each trial of the concatenated samples that has a step."""
    for s in range(seg.size - 1):
        if seg[s + 1] - seg[s] >= 2:
            yield x[seg[s] : seg[s + 1]], y[seg[s] : seg[s + 1]]


def thesis_start(x: FloatArray, y: FloatArray, seg: npt.NDArray[np.int64]) -> BoucWenParams:
    """Figure 56 initial guess: A = 1, n = 1 and, for each Table 4 phase, the median (the thesis averages;
    noise on steep steps must not dominate) ``Psi`` of Eq 23 solved for it on every step where it is
    defined (``(A - dz/dx) / |z|^n``), then Eq 25."""
    A0, n0 = 1.0, 1.0
    psi = np.zeros(6)
    per_phase: list[list[FloatArray]] = [[] for _ in range(6)]
    for xs, ys in _trials(x, y, seg):
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
    for xs, ys in _trials(x, y, seg):
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


def _diverges_when_decimated(u: FloatArray, screen: Problem, problem: Problem) -> bool:
    """True when the recursion with parameters `u` stays bounded on the coarse screening copy but diverges
    on the (finer) fitted samples (each check stops at the first divergence)."""
    on_screen = screen.diverges(u)
    screen.nfev -= 1  # checks, not steps of a solve
    if on_screen:
        return False
    diverged = problem.diverges(u)
    problem.nfev -= 1
    return diverged


class _Solved(NamedTuple):
    """The outcome of the multi-start solve: the problem of the fitted samples and its best point, the
    last solve's status and message, and the convergence record of :class:`.BoucWenFit`."""

    problem: Problem
    strides: tuple[int, ...]
    u: FloatArray
    status: int
    message: str
    n_starts: int
    nfev: int
    start_rmse_nm: tuple[float, ...]
    polished_rmse_nm: tuple[float, ...]


def _solve_segments(segments: list[tuple[FloatArray, FloatArray]], options: FitOptions) -> _Solved:
    """The multi-start solve of :func:`fit` on validated segments (the procedure is described there)."""
    starts, max_samples_per_trial = options.starts, options.max_samples_per_trial
    scheme, bounds = options.scheme, options.bounds
    if starts < 0:
        raise InvalidInput(f"starts must be >= 0, got {starts}")
    if max_samples_per_trial is not None and max_samples_per_trial < 3:
        raise InvalidInput(f"max_samples_per_trial must be at least 3, got {max_samples_per_trial}")
    angle_scale = max(float(np.max(np.abs(x))) for x, _ in segments)
    torque_scale = max(float(np.max(np.abs(y))) for _, y in segments)
    scale = FitScale(angle_scale, torque_scale)
    x, y, seg, strides = decimate(segments, max_samples_per_trial)
    check_scheme(scheme, None)
    if scheme == REFINED:
        # integrate along every sample, compare at the decimated ones (the same angle path at any stride)
        problem = _path_problem(segments, strides, bounds, scale, None)
    else:
        problem = Problem(Samples(x, y, seg), bounds, scale, scheme)
    screen_samples = (
        _SCREEN_SAMPLES if max_samples_per_trial is None else min(_SCREEN_SAMPLES, max_samples_per_trial)
    )
    xs, ys, segs, screen_strides = decimate(segments, screen_samples)
    # the screening copy is also integrated with longer substeps (its cost is set by the angle travelled)
    screen_step = SCREEN_STEP_DEG if scheme == REFINED else None
    mid: Problem | None = None
    if scheme == REFINED:
        # starts are screened, then polished, on decimated copies (their angle path is the samples kept,
        # close to the full one for smooth data); the last steps run on the full path
        screen = Problem(Samples(xs, ys, segs), bounds, scale, scheme, screen_step)
        xm, ym, segm, mid_strides = decimate(segments, _MID_SAMPLES)
        if any(m > k for m, k in zip(mid_strides, strides, strict=True)):
            # a fit that ends on this copy keeps the angle's turning points in it (it is then the fit)
            copy = (
                Samples(xm, ym, segm) if options.final_solve else turning_point_copy(segments, _MID_SAMPLES)
            )
            mid = Problem(copy, bounds, scale, scheme, MID_STEP_DEG)
    elif screen_strides == strides:
        screen = problem
    else:
        screen = Problem(Samples(xs, ys, segs), bounds, scale, scheme, screen_step)

    candidates: list[FloatArray] = []
    if options.initial is not None:
        initial = options.initial
        for p in [initial] if isinstance(initial, BoucWenParams) else list(initial):
            candidates.append(problem.to_u(p))
    if options.data_starts:
        candidates.append(problem.to_u(thesis_start(xs, ys, segs)))
        ee = equation_error_start(xs, ys, segs, np.linspace(bounds.n_min, bounds.n_max, 11))
        if ee is not None:
            candidates.append(problem.to_u(ee))
    if starts > 0:
        unit = qmc.Halton(d=8, scramble=True, rng=options.seed).random(starts)
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
        and scheme == EQ23
        and any(s > 1 for s in strides)
        and _diverges_when_decimated(short[0][1], screen, problem)
    ):
        # The best start is stable on the coarse copy but its recursion diverges on the decimated samples:
        # explicit-Euler steps of the decimated data misbehave for this loop (a range-of-motion stop makes
        # it nearly vertical), so a fit there would not carry over to every sample. Polish on every
        # sample instead (fit_trials' guard would otherwise redo it there, after a wasted decimated fit).
        x, y, seg, strides = decimate(segments, None)
        problem = Problem(Samples(x, y, seg), bounds, scale, scheme)
    # Stage 2: the best few are refined to convergence on the fitted samples; the lowest cost wins.
    # A short solve that ended at the cost of one already chosen (within 0.1 %: the same valley) or
    # clearly above the best (by 5 %) is not polished.
    chosen: list[FloatArray] = []
    chosen_cost: list[float] = []
    for cost0, u0 in short:
        if len(chosen) >= max(1, options.polish) or cost0 > 1.05 * short[0][0]:
            break
        if all(abs(cost0 - c) > 1e-3 * c for c in chosen_cost):
            chosen.append(u0)
            chosen_cost.append(cost0)
    polish_tol = options.polish_tol
    best: tuple[float, FloatArray, int, str] | None = None
    polished: list[float] = []
    last = problem if mid is None or options.final_solve else mid  # the problem of the last solves
    for u0 in chosen:
        if mid is not None:
            u0, cost, status, message = mid.solve(
                u0, max_nfev=_POLISH_NFEV, tol=polish_tol, ftol=options.polish_ftol
            )
            nfev, tol = _FINAL_NFEV, max(polish_tol, _FINAL_TOL)
            ftol: float | None = FINAL_FTOL  # started close
        else:
            nfev, tol, ftol = _POLISH_NFEV, polish_tol, None
        if last is problem:
            u0, cost, status, message = problem.solve(u0, max_nfev=nfev, tol=tol, ftol=ftol)
        polished.append(last.rmse(cost))
        if best is None or cost < best[0]:
            best = (cost, u0, status, message)
    assert best is not None
    return _Solved(
        problem=last,
        strides=strides,
        u=best[1],
        status=best[2],
        message=best[3],
        n_starts=len(candidates),
        nfev=problem.nfev + (screen.nfev if screen is not problem else 0) + (mid.nfev if mid else 0),
        start_rmse_nm=tuple(screen.rmse(c) for c, _ in short),
        polished_rmse_nm=tuple(polished),
    )


def fitted_params(segments: list[tuple[FloatArray, FloatArray]], options: FitOptions) -> BoucWenParams:
    """The parameters :func:`_fit_segments` finds, without its record: a held-out fit's."""
    solved = _solve_segments(segments, options)
    return solved.problem.params(solved.u)


def _fit_segments(segments: list[tuple[FloatArray, FloatArray]], options: FitOptions) -> BoucWenFit:
    solved = _solve_segments(segments, options)
    problem = solved.problem
    params = problem.params(solved.u)
    std = param_std(problem, params)  # its Jacobian comes with the torque along the fitted path:
    torques = trial_torques(problem, segments, options.scheme)  # every sample's when that path is theirs
    if torques is None:
        rmse, r2, per, diverged = evaluate(segments, params, problem.bound, options.scheme)
    else:
        rmse, r2, per, diverged = scores(segments, torques, problem.diverged_at >= 0)
    return BoucWenFit(
        params=params,
        rmse_nm=rmse,
        r2=r2,
        param_std=std,
        n_starts=solved.n_starts,
        converged=solved.status > 0,
        diverged=diverged,
        trial_rmse_nm=per,
        n_samples=sum(s[0].size for s in segments),
        n_samples_fitted=problem.y_rows.size,
        stride=solved.strides,
        nfev=solved.nfev,
        angle_scale_deg=problem.X,
        torque_scale_nm=problem.Z,
        bounds=options.bounds,
        message=solved.message,
        scheme=options.scheme,
        status=solved.status,
        start_rmse_nm=solved.start_rmse_nm,
        polished_rmse_nm=solved.polished_rmse_nm,
    )


def fit(
    x_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    trials: Sequence[int] | None = None,
    **options: Unpack[FitKeywords],
) -> BoucWenFit:
    """Fit the generalised Bouc-Wen model (Eq 20-23) to angle/torque samples by least squares (§6.2.3).

    The samples are fitted as given - no centring here (the thesis centres each trial on (0, 0) first,
    note under Table 4; do that before calling).  The recursion starts at ``z0 = torque_nm[0]``.

    trials: lengths of consecutive trials making up ``x_deg``/``torque_nm`` (summing to its length), each
        restarting the recursion at its own first torque; ``None``: one trial (:func:`fit_trials` takes a
        list of segments).
    options: starts, initial, data_starts, bounds, seed, max_samples_per_trial (default 8000), polish and
        scheme (default ``"refined"``), see :class:`.FitOptions`.  With the refined scheme the integration
        follows the angle between the kept samples, so decimating smooth data only drops residuals; with
        ``scheme="eq23"`` the explicit-Euler error grows with the angle step.  RMSE and R^2 are on every
        given sample.

    Procedure: every start gets a short trust-region solve (``scipy.optimize.least_squares``, analytic
    Jacobian, bounds) on a coarse copy of the data (at most 400 samples per trial); the best ``polish``
    distinct ones are refined on the fitted samples and the lowest cost wins (on every sample when the best
    start's Eq 23 recursion diverges only on the decimated samples).  A start whose recursion diverges is
    first pulled toward a straight line of the loop's mean slope until it no longer does; during the solve
    a diverged torque is held at 10x the data's torque scale, a large finite penalty.
    """
    x = as_angle(x_deg)
    y = as_angle(torque_nm, "torque_nm")
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
    return fit_trials(segments, **options)


@blas_single_threaded
def fit_trials(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    backbone_degree: int | None = None,
    backbone_factory: BackboneFactory | None = None,
    **options: Unpack[FitKeywords],
) -> BoucWenFit:
    """Fit one model jointly to several trials ``[(angle_deg, torque_nm), ...]`` of one configuration.

    Each trial starts its own Eq 23 recursion at its own first torque.  Options as in :func:`fit`.

    backbone_degree: ``None`` fits the thesis form ``torque = z``; an integer fits ``torque = g(angle) + z``
        with ``g`` a polynomial of that degree through every sample (:mod:`.backbone`), then the Bouc-Wen
        state to what is left; the result's ``backbone`` holds ``g`` and its errors are of the whole torque.
    backbone_factory: instead of a polynomial, ``g`` given from outside and held fixed (e.g. the device's
        elastic elements, :class:`.backbone.FixedBackbone`), called with the indices of all the trials.

    Decimation guard (``scheme="eq23"`` only): where a fit on decimated samples does not carry over to
    every sample (R^2 below FULL_REFIT_R2 or divergence, e.g. at a range-of-motion stop), it is redone on
    every sample and the better of the two (by RMSE on every sample) is returned.
    """
    checked = _validate_segments(segments)
    backbone = backbone_for(checked, range(len(checked)), backbone_degree, backbone_factory)
    if backbone is not None:
        checked = _validate_segments(hysteretic_part(checked, backbone))
    settings = FitOptions(**options)
    result = _fit_segments(checked, settings)
    decimated = any(s > 1 for s in result.stride)
    if settings.scheme == EQ23 and decimated and (result.diverged or not result.r2 >= FULL_REFIT_R2):
        every_sample = replace(
            settings, starts=0, initial=result.params, data_starts=False, max_samples_per_trial=None, polish=1
        )
        full = _fit_segments(checked, every_sample)
        if full.rmse_nm < result.rmse_nm:
            result = full
    bound = DIVERGENCE_FACTOR * result.torque_scale_nm
    return replace(
        result,
        rmse_refined_nm=refined_rmse(checked, result.params, bound, settings.scheme),
        backbone=backbone,
    )


HELD_OUT_FTOL = 1e-5  # a held-out fit's polish ends at this relative cost decrease (docs/analysis.md)


@blas_single_threaded
def cross_validate(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    backbone_degree: int | None = None,
    backbone_factory: BackboneFactory | None = None,
    **options: Unpack[FitKeywords],
) -> list[float]:
    """Leave-one-trial-out RMSE (N*m): for each trial, fit the others and predict the held-out trial from
    its own first torque.  Needs at least two trials.

    Each held-out fit is a multi-start fit of its own on the other trials (options as in
    :func:`.fit_trials`): nothing computed from the held-out trial enters it.  It ends with its polish (to
    ``HELD_OUT_FTOL``) on the mid-size copy of the other trials that keeps their angle's turning points,
    not with a last solve on the fitted samples (within 1 % of the full procedure's held-out error,
    docs/analysis.md).  A parameter only the held-out trial determines stays where the other trials leave
    it, and the held-out error shows it.

    backbone_degree: as in :func:`.fit_trials`; each held-out fit then fits its backbone on the other
        trials too, and the held-out prediction is ``g(angle) + z``.
    backbone_factory: as in :func:`.fit_trials`; called with the other trials' indices for each held-out
        fit (a factory that fits ``g`` fits it on those trials only).
    initial: extra start(s) for every held-out fit.  It must not have been fitted on the held-out trial
        (a fit on all trials would carry the held-out trial into its own test); ``None`` by default.
    """
    checked = _validate_segments(segments)
    if len(checked) < 2:
        raise InvalidInput(f"cross-validation needs at least 2 trials, got {len(checked)}")
    held_out_fit = replace(
        FitOptions(**options), polish_tol=1e-8, polish_ftol=HELD_OUT_FTOL, final_solve=False
    )
    errors: list[float] = []
    for k, (x, y) in enumerate(checked):
        others = [s for j, s in enumerate(checked) if j != k]
        indices = [j for j in range(len(checked)) if j != k]
        backbone = backbone_for(others, indices, backbone_degree, backbone_factory)
        if backbone is not None:
            others = hysteretic_part(others, backbone)
            x, y = hysteretic_part([(x, y)], backbone)[0]
        params = fitted_params(others, held_out_fit)
        scale = max(float(np.max(np.abs(y))), max(float(np.max(np.abs(yy))) for _, yy in others))
        rmse, _, _, _ = evaluate([(x, y)], params, DIVERGENCE_FACTOR * scale, held_out_fit.scheme)
        errors.append(rmse)
    return errors
