"""The fit's shortcuts give the numbers of the long way: the fused residual-and-Jacobian evaluation, the
Jacobian at the compared rows only and the solver's reuse of the start check are exact; the early stops of the polish and the last solve change the RMSE, and the held-out fits'
end on the turning-point copy the held-out errors, by less than their documented tolerances."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.models.bouc_wen import fitting
from protocol_runner.models.bouc_wen.copies import _path_problem, decimate
from protocol_runner.models.bouc_wen.fitting import cross_validate, fit_trials
from protocol_runner.models.bouc_wen.problem import FitScale, Problem, Samples
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS
from protocol_runner.models.bouc_wen.schemes import (
    BoucWenShape,
    Integration,
    Sensitivity,
    run_scheme,
)


def _loop_halves() -> list[tuple[np.ndarray, np.ndarray]]:
    """Configuration 1's centred dry-run loop (range-of-motion stops), cut into two trials."""
    data = np.load(Path(__file__).resolve().parent / "data" / "brace_rom_stop_loop.npz")
    x = data["angle_deg"].astype(np.float64)
    y = data["torque_nm"].astype(np.float64)
    half = x.size // 2
    return [(x[:half], y[:half]), (x[half:], y[half:])]


def _path(max_samples: int) -> Problem:
    segments = _loop_halves()
    _, _, _, strides = decimate(segments, max_samples)
    return _path_problem(segments, strides, DEFAULT_BOUNDS, FitScale(40.0, 20.0), None)


def test_a_fused_evaluation_gives_the_residuals_and_jacobian_of_separate_ones() -> None:
    problem = _path(3000)
    u = np.array([3.0, 1.1, 5.0, -4.0, 2.0, 1.0, -3.0, 0.5])
    plain_r = problem.residuals(u).copy()
    plain_j = problem.jacobian(u).copy()
    problem.fused = True
    fused_r = problem.residuals(u)
    fused_j = problem.jacobian(u)
    problem.fused = False
    assert np.array_equal(fused_r, plain_r)
    assert np.array_equal(fused_j, plain_j)
    # the cache answers only for the very point evaluated
    other = u.copy()
    other[0] = 3.5
    assert not np.array_equal(problem.jacobian(other), plain_j)


def test_the_jacobian_at_the_compared_rows_is_those_rows_of_the_full_one() -> None:
    problem = _path(3000)
    assert problem.rows is not None and problem.rows.size < problem.x.size
    A, n, beta = 0.2, 1.1, np.array([0.01, 0.1, -0.1, -0.08, 0.09, 0.0])
    z_full = np.empty_like(problem.x)
    full = np.empty((problem.x.size, 8))
    run_scheme(
        problem.x,
        problem.seg,
        problem.z0,
        BoucWenShape(A, n, beta),
        Integration("refined", problem.bound, True),
        z_full,
        Sensitivity(full, np.eye(8)),
    )
    rows_only = problem.physical_jacobian(A, n, beta)
    assert np.array_equal(rows_only, full[problem.rows])
    assert np.array_equal(problem.z, z_full)


def test_the_early_stops_keep_the_rmse_within_their_tolerance(monkeypatch: pytest.MonkeyPatch) -> None:
    """Against a polish on the mid-size copy run to its step tolerance (polish_ftol None) and a last solve
    run to a relative cost change of 1e-8: the fit's RMSE within 1e-4 (POLISH_FTOL and FINAL_FTOL 1e-5),
    with no more residual evaluations. With the knee campaign's 8 starts: with 4, on an AVX2 processor
    without AVX-512, both procedures end in local optima 15 % above the one 8 starts find, 2.856 and
    2.847 N*m, which then differ by 0.33 % (docs/analysis.md), a comparison of two basins rather than of
    the early stops."""
    segments = _loop_halves()
    fast = fit_trials(segments, starts=8, backbone_degree=9)
    monkeypatch.setattr(fitting, "FINAL_FTOL", 1e-8)
    options = fitting.FitOptions
    monkeypatch.setattr(fitting, "FitOptions", lambda **kw: replace(options(**kw), polish_ftol=None))
    strict = fit_trials(segments, starts=8, backbone_degree=9)
    assert fast.rmse_nm == pytest.approx(strict.rmse_nm, rel=1e-4)
    assert fast.nfev <= strict.nfev


def test_held_out_fits_ending_on_the_turning_point_copy_keep_the_held_out_errors(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A held-out fit ends with its polish on the mid-size copy that keeps the angle's turning points
    (FitOptions.final_solve False); the full procedure (polish on the decimated copy, then a last solve on
    the fitted samples, both to 1e-8) gives held-out errors within 1 % of it (docs/analysis.md: 0.96 % at
    most over the 60 held-out trials of the knee dry run, median 1.8e-4)."""
    segments = _loop_halves()
    fast_cv = cross_validate(segments, starts=1, backbone_degree=9)
    fitted_params = fitting.fitted_params
    monkeypatch.setattr(
        fitting,
        "fitted_params",
        lambda s, o: fitted_params(s, replace(o, polish_ftol=None, final_solve=True)),
    )
    monkeypatch.setattr(fitting, "FINAL_FTOL", 1e-8)
    full_cv = np.array(cross_validate(segments, starts=1, backbone_degree=9))
    np.testing.assert_allclose(fast_cv, full_cv, rtol=1e-2)
    # the turning points make it close: ending on the plain decimated copy misses by more than twice as much
    monkeypatch.setattr(fitting, "fitted_params", fitted_params)
    monkeypatch.setattr(fitting, "turning_point_copy", lambda s, m: Samples(*decimate(s, m)[:3]))
    plain_cv = cross_validate(segments, starts=1, backbone_degree=9)
    assert np.max(np.abs(plain_cv / full_cv - 1.0)) > 2.0 * np.max(np.abs(fast_cv / full_cv - 1.0))


def test_a_start_that_needs_no_contraction_is_evaluated_once_by_its_solve(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The start check of Problem.stabilise is fused, so for a start strictly inside the bounds the
    solver's first evaluation is that check: the problem's residual evaluations are exactly the solver's.
    A start on a bound is moved inside by the solver and evaluated there once more. Either way the solve
    ends where one without the reuse does."""
    from protocol_runner.models.bouc_wen import problem as bw_problem

    counts: list[int] = []
    least_squares = bw_problem.least_squares

    def counting(*args: object, **kwargs: object) -> object:
        res = least_squares(*args, **kwargs)  # type: ignore[arg-type]
        counts.append(int(res.nfev))
        return res

    monkeypatch.setattr(bw_problem, "least_squares", counting)
    inside = np.array([1.0, 1.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    on_bound = np.array([1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # n on its lower bound: a straight line
    for u0, extra in ((inside, 0), (on_bound, 1)):
        counts.clear()
        problem = _path(3000)
        u, cost, _, _ = problem.solve(u0, max_nfev=4, tol=1e-8)
        assert problem.nfev == counts[0] + extra
        # the same solve with every evaluation made afresh
        fresh = _path(3000)
        monkeypatch.setattr(fresh, "_solver_residuals", fresh.residuals)
        u_fresh, cost_fresh, _, _ = fresh.solve(u0, max_nfev=4, tol=1e-8)
        assert fresh.nfev == counts[1] + 1
        assert np.array_equal(u, u_fresh) and cost == cost_fresh
