"""The fit's divergence checks stop at the first diverged sample, and the evaluations it would make twice
are made once: the fitted parameters, errors, intervals and held-out errors are those of the
long way, bit for bit.

The long way (as the fit ran before): every start check integrates every trial to the end by the torque
alone, the solver evaluates its start afresh, every Jacobian is computed afresh, and the errors on every
sample come from their own integration.  The data are multi-trial loops whose quasi-random starts do
diverge, so the early stops are exercised (counted)."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.models.bouc_wen import copies, fitting
from protocol_runner.models.bouc_wen import problem as bw_problem
from protocol_runner.models.bouc_wen.fitting import cross_validate, fit_trials
from protocol_runner.models.bouc_wen.identifiability import identify
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import (
    FitScale,
    Problem,
    Samples,
    evaluate,
    trial_torques,
)
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS
from protocol_runner.models.bouc_wen.schemes import BoucWenShape, Integration, Sensitivity, run_scheme
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
# Psi < 0 in every phase: |z| grows without bound once |z|^n outweighs A (a divergent parameter set)
RUNAWAY = BoucWenShape(1.0, 2.0, np.full(6, -0.05))


def _knee_trials(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Configuration 1's centred dry-run loop (range-of-motion stops), cut into ``count`` trials."""
    data = np.load(Path(__file__).resolve().parent / "data" / "brace_rom_stop_loop.npz")
    x = data["angle_deg"].astype(np.float64)
    y = data["torque_nm"].astype(np.float64)
    edges = np.linspace(0, x.size, count + 1).astype(int)
    return [(x[a:b], y[a:b]) for a, b in itertools.pairwise(edges)]


def _simulated_trials() -> list[tuple[np.ndarray, np.ndarray]]:
    """Three trials of the thesis's Figure 57 parameters at growing amplitudes, with a little noise."""
    rng = np.random.default_rng(3)
    trials = []
    for amplitude in (30.0, 45.0, 60.0):
        x = amplitude * np.sin(2 * np.pi * np.arange(1200) / 400.0)
        y = simulate(x, FIG57, z0=0.0) + 0.05 * rng.standard_normal(x.size)
        trials.append((x, y))
    return trials


def _bits(value: object) -> object:
    """A comparable form of a fit record's field in which equal means bit for bit equal."""
    if isinstance(value, float | np.floating | np.ndarray):
        return np.asarray(value, dtype=np.float64).tobytes()
    if isinstance(value, tuple | list):
        return tuple(_bits(v) for v in value)
    if isinstance(value, BoucWenParams):
        return _bits(value.as_array())
    return value


def _record(fit: object) -> dict[str, object]:
    """Every field of a fit record except the count of residual evaluations (fewer the short way)."""
    fields = dataclasses.fields(fit)  # type: ignore[arg-type]
    return {f.name: _bits(getattr(fit, f.name)) for f in fields if f.name not in ("nfev", "backbone")}


def _the_long_way(monkeypatch: pytest.MonkeyPatch) -> None:
    def whole_check(self: Problem, u: np.ndarray) -> bool:
        fused, self.fused = self.fused, False
        try:
            self.residuals(u)  # the torque alone, every trial to its end
        finally:
            self.fused = fused
        return self.diverged_at >= 0

    def fresh_jacobian(self: Problem, u: np.ndarray) -> np.ndarray:
        A, n, beta = self.physical(u)
        return self.physical_jacobian(A, n, beta, self._chain(n, beta) / self.Z)

    monkeypatch.setattr(Problem, "diverges", whole_check)
    monkeypatch.setattr(Problem, "_solver_residuals", Problem.residuals)
    monkeypatch.setattr(Problem, "jacobian", fresh_jacobian)
    monkeypatch.setattr(fitting, "trial_torques", lambda problem, segments, scheme: None)


def test_a_check_stops_at_the_first_divergence_and_changes_nothing_without_one() -> None:
    x = 50.0 * np.sin(2 * np.pi * np.arange(900) / 300.0)
    seg = np.array([0, 300, 600, 900])
    z0 = np.zeros(3)
    for scheme in ("refined", "eq23"):
        whole, early = np.full(x.size, 7.0), np.full(x.size, 7.0)
        full = Integration(scheme, 100.0)
        bad = run_scheme(x, seg, z0, RUNAWAY, full, whole)
        assert 0 < bad < seg[1]  # the first trial diverges: the others are integrated the long way
        assert np.all(np.isfinite(whole[seg[1] :])) and not np.any(whole[seg[1] :] == 7.0)
        stop = full._replace(stop_at_divergence=True)
        assert run_scheme(x, seg, z0, RUNAWAY, stop, early) == bad
        assert np.array_equal(early[:bad], whole[:bad])
        # nothing after the first diverged sample was integrated in its trial, and the later trials (which
        # the refined kernel integrates beside it, three at a time) were not integrated to their end
        assert np.all(early[bad : seg[1]] == 7.0)
        assert not np.array_equal(early[seg[1] :], whole[seg[1] :])
        # a set that stays bounded: the same torque and derivatives, bit for bit
        shape = BoucWenShape(FIG57.A, FIG57.n, np.array(FIG57.beta))
        outputs = []
        for how in (full, stop):
            z, dz = np.empty_like(x), np.empty((x.size, 8))
            assert run_scheme(x, seg, z0, shape, how, z, Sensitivity(dz)) == -1
            outputs.append((z, dz))
        assert np.array_equal(outputs[0][0], outputs[1][0]) and np.array_equal(outputs[0][1], outputs[1][1])


def test_a_check_that_diverges_keeps_nothing_for_the_solver() -> None:
    trials = _simulated_trials()
    x = np.concatenate([t[0] for t in trials])
    y = np.concatenate([t[1] for t in trials])
    problem = Problem(Samples(x, y, np.array([0, 1200, 2400, 3600])), DEFAULT_BOUNDS, FitScale(60.0, 2.0))
    good = problem.to_u(FIG57)
    problem.fused = True
    assert not problem.diverges(good)
    r = problem.residuals(good).copy()
    assert problem._cached is not None and np.array_equal(problem._solver_residuals(good), r)
    runaway = good.copy()
    runaway[2:] = problem.lower[2:]  # psi' at their lower bounds: Psi < 0, the loop runs away
    assert problem.diverges(runaway)
    assert problem._cached is None
    assert 0 < problem.diverged_at < 1200  # stopped in the first trial


@pytest.mark.parametrize(
    ("data", "options"),
    [
        (_knee_trials(2), {"starts": 8, "backbone_degree": 9}),
        (_knee_trials(3), {"starts": 6, "backbone_degree": 9, "seed": 5}),
        (_simulated_trials(), {"starts": 8}),
        (
            _knee_trials(2),
            {"starts": 8, "scheme": "eq23", "max_samples_per_trial": 500, "backbone_degree": 9},
        ),
    ],
    ids=["knee-2-trials", "knee-3-trials", "fig57-3-trials", "knee-eq23-decimated"],
)
def test_the_fit_identification_and_cross_validation_are_those_of_the_long_way(
    monkeypatch: pytest.MonkeyPatch, data: list[tuple[np.ndarray, np.ndarray]], options: dict[str, object]
) -> None:
    stopped = [0]

    def counting(*args: object) -> int:
        bad = run_scheme(*args)  # type: ignore[arg-type]
        stopped[0] += bad >= 0 and args[4].stop_at_divergence  # type: ignore[attr-defined]
        return bad

    monkeypatch.setattr(bw_problem, "run_scheme", counting)
    fit = identify(data, fit_trials(data, **options))  # type: ignore[arg-type]
    cv = cross_validate(data[:2], **options)  # type: ignore[arg-type]
    assert stopped[0] > 0  # starts did diverge, and their checks stopped there

    monkeypatch.undo()
    _the_long_way(monkeypatch)
    long_fit = identify(data, fit_trials(data, **options))  # type: ignore[arg-type]
    long_cv = cross_validate(data[:2], **options)  # type: ignore[arg-type]
    assert _record(fit) == _record(long_fit)
    assert _bits(cv) == _bits(long_cv)
    assert fit.nfev < long_fit.nfev  # a contracted start's passing check was the solver's first evaluation


def test_the_errors_on_every_sample_come_from_the_fitted_path_only_when_it_is_every_sample() -> None:
    trials = _simulated_trials()
    fit = fit_trials(trials, starts=2)
    bound = 10.0 * fit.torque_scale_nm
    rmse, r2, per, diverged = evaluate(trials, fit.params, bound)
    assert (fit.rmse_nm, fit.r2, fit.trial_rmse_nm, fit.diverged) == (rmse, r2, per, diverged)
    # a decimated copy's torque is not every sample's, nor is another scheme's or substep's
    x, y, seg, _ = copies.decimate(trials, 600)
    scale = FitScale(fit.angle_scale_deg, fit.torque_scale_nm)
    assert trial_torques(Problem(Samples(x, y, seg), DEFAULT_BOUNDS, scale), trials, "refined") is None
    x, y, seg, _ = copies.decimate(trials, None)
    assert trial_torques(Problem(Samples(x, y, seg), DEFAULT_BOUNDS, scale), trials, "refined") is not None
    assert trial_torques(Problem(Samples(x, y, seg), DEFAULT_BOUNDS, scale), trials, "eq23") is None
    coarse = Problem(Samples(x, y, seg), DEFAULT_BOUNDS, scale, max_step_deg=0.5)
    assert trial_torques(coarse, trials, "refined") is None


def test_the_decimation_guard_checks_stop_early_and_are_not_counted() -> None:
    """_diverges_when_decimated: bounded on the first problem and divergent on the second gives True, a
    first problem on which the recursion already diverges gives False without a check of the second; the
    checks stop at the first divergence and are not counted as evaluations."""
    trials = _simulated_trials()

    def one_trial(x: np.ndarray, y: np.ndarray) -> Problem:
        return Problem(Samples(x, y, np.array([0, x.size])), DEFAULT_BOUNDS, FitScale(60.0, 2.0), "eq23")

    small = one_trial(trials[0][0] / 6.0, trials[0][1] / 6.0)
    large = one_trial(*trials[2])
    u = large.to_u(FIG57)
    u[2:] = large.lower[2:] / 8.0  # Psi < 0: a loop that runs away once |z| is large enough
    large.z[:] = 7.0
    assert fitting._diverges_when_decimated(u, small, large)
    assert small.diverged_at == -1 and 0 < large.diverged_at < large.x.size - 1
    assert np.all(large.z[large.diverged_at :] == 7.0)  # the check stopped there
    assert small.nfev == large.nfev == 0
    small.diverged_at = -7
    assert not fitting._diverges_when_decimated(u, large, small)
    assert small.diverged_at == -7 and small.nfev == large.nfev == 0
