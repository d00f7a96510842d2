"""Contracts of the Bouc-Wen fitter's options: what `n_starts`, `stride` and `n_samples_fitted` report,
and the clear errors for options that cannot work."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.fitting import fit, fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _trial(n: int, phase: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    x = 60.0 * np.sin(2 * np.pi * np.arange(n) / 160.0 + phase)
    return x, simulate(x, FIG57, z0=0.0)


def test_n_starts_counts_every_starting_point_tried() -> None:
    segments = [_trial(240)]
    assert fit_trials(segments, starts=3, data_starts=False).n_starts == 3
    assert fit_trials(segments, starts=0, initial=[FIG57, FIG57], data_starts=False).n_starts == 2
    # the Figure 56 start and the equation-error start (defined on this well-sampled loop)
    assert fit_trials(segments, starts=0, data_starts=True).n_starts == 2
    assert fit_trials(segments, starts=2, initial=FIG57, data_starts=True).n_starts == 5


def test_each_trial_is_decimated_by_the_smallest_stride_that_fits_the_limit() -> None:
    segments = [_trial(900), _trial(400, 1.0), _trial(300, 2.0)]
    result = fit_trials(segments, starts=0, max_samples_per_trial=300)
    assert result.stride == (3, 2, 1)
    assert result.n_samples_fitted == math.ceil(900 / 3) + math.ceil(400 / 2) + 300
    assert result.n_samples == 1600
    unlimited = fit_trials(segments, starts=0, max_samples_per_trial=None)
    assert unlimited.stride == (1, 1, 1) and unlimited.n_samples_fitted == 1600


def test_a_warm_start_at_the_answer_is_kept() -> None:
    x, y = _trial(240)
    result = fit(x, y, starts=0, initial=FIG57, data_starts=False)
    assert result.converged
    np.testing.assert_allclose(result.params.as_array(), FIG57.as_array(), rtol=1e-6, atol=1e-9)
    assert result.rmse_nm < 1e-8 and result.r2 == pytest.approx(1.0)
    assert "termination condition is satisfied" in result.message  # the solver's own words


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"starts": -1}, "starts must be >= 0"),
        ({"max_samples_per_trial": 2}, "at least 3"),
        ({"starts": 0, "data_starts": False}, "no starting point"),
    ],
)
def test_options_that_cannot_work_are_invalid_input(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        fit_trials([_trial(50)], **kwargs)


def test_trials_that_cannot_be_fitted_are_named() -> None:
    x, y = _trial(50)
    with pytest.raises(InvalidInput, match="trial 1 has 2 samples"):
        fit_trials([(x, y), (x[:2], y[:2])])
    with pytest.raises(InvalidInput, match="trial 0 must be a pair"):
        fit_trials([(x, y, y)])  # type: ignore[list-item]
    with pytest.raises(InvalidInput, match="positive lengths"):
        fit(x, y, trials=[50, 0])
    assert fit_trials([(x, y), (x[:3], y[:3])], starts=0).n_samples == 53  # three samples are enough


def test_nfev_counts_the_residual_evaluations_of_the_solves(monkeypatch: pytest.MonkeyPatch) -> None:
    """nfev: every residual evaluation made by the least-squares solves and every check of their start
    stabilisation; the decimation guard's divergence checks between the stages are not solve steps."""
    from protocol_runner.models.bouc_wen.problem import Problem

    in_solve = [0]
    counted = [0]
    residuals, diverges, solve = Problem.residuals, Problem.diverges, Problem.solve

    def counting_residuals(self: Problem, u: np.ndarray) -> np.ndarray:
        counted[0] += in_solve[0] > 0
        return residuals(self, u)

    def counting_checks(self: Problem, u: np.ndarray) -> bool:
        counted[0] += in_solve[0] > 0
        return diverges(self, u)

    def flagged_solve(self: Problem, *args: object, **kwargs: object) -> object:
        in_solve[0] += 1
        try:
            return solve(self, *args, **kwargs)  # type: ignore[arg-type]
        finally:
            in_solve[0] -= 1

    monkeypatch.setattr(Problem, "residuals", counting_residuals)
    monkeypatch.setattr(Problem, "diverges", counting_checks)
    monkeypatch.setattr(Problem, "solve", flagged_solve)
    plain = fit_trials([_trial(240)], starts=2)  # short enough that nothing is decimated
    assert plain.stride == (1,) and plain.nfev == counted[0] > plain.n_starts
    counted[0] = 0
    decimated = fit_trials([_trial(1200)], starts=2, max_samples_per_trial=600)  # screened on 400 a trial
    assert decimated.stride == (2,) and decimated.nfev == counted[0] > decimated.n_starts
    counted[0] = 0  # Eq 23 on decimated samples: the divergence checks of the decimation guard run too
    checked = fit_trials([_trial(1200)], starts=2, max_samples_per_trial=600, scheme="eq23")
    assert checked.stride == (2,) and checked.nfev == counted[0] > checked.n_starts


def test_a_solve_stopped_by_its_evaluation_limit_is_not_converged(monkeypatch: pytest.MonkeyPatch) -> None:
    from protocol_runner.models.bouc_wen import fitting

    monkeypatch.setattr(fitting, "_POLISH_NFEV", 2)
    x, y = _trial(240)
    result = fit(x, y, starts=0, initial=BoucWenParams(A=0.5, n=1.0, beta=(0.0,) * 6), data_starts=False)
    assert not result.converged
    assert "maximum number of function evaluations" in result.message
