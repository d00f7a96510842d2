"""BLAS threads while a fit runs: held at one by threadpoolctl inside the fit, whatever
the caller set, and the caller's setting restored afterwards - even though numpy was imported long before
(here by pytest's collection), which is where environment variables set at import time do nothing."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from protocol_runner.models.bouc_wen.fitting import cross_validate, fit_trials
from protocol_runner.models.bouc_wen.identifiability import identify
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import Problem
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def _blas_threads() -> list[int]:
    return [int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]


def test_every_fit_entry_point_runs_blas_single_threaded_and_restores_the_callers_setting(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    x = 60.0 * np.sin(2 * np.pi * np.arange(300) / 150.0)
    segments = [(x, simulate(x, FIG57, 0.0)), (x, simulate(x, FIG57, 0.5))]
    seen: list[list[int]] = []
    solve = Problem.solve

    def spying_solve(self: Problem, *args: object, **kwargs: object) -> object:
        seen.append(_blas_threads())
        return solve(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Problem, "solve", spying_solve)
    with threadpool_limits(limits=2, user_api="blas"):
        if not _blas_threads() or max(_blas_threads()) < 2:
            pytest.skip("this BLAS cannot run two threads: nothing to hold down")
        result = fit_trials(segments, starts=1)
        fitted = len(seen)
        cross_validate(segments, starts=1)
        assert len(seen) > fitted
        identify(segments, result)
        assert max(_blas_threads()) == 2  # the caller's setting is back
    assert seen and all(threads and max(threads) == 1 for threads in seen)
