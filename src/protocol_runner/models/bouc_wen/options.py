"""The options of a Bouc-Wen fit (thesis §6.2.3, Figure 56): one record that :func:`.fit`,
:func:`.fit_trials` and :func:`.cross_validate` fill from their keywords and hand to the fitter."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

from .params import BoucWenParams
from .records import DEFAULT_BOUNDS, BoucWenBounds
from .schemes import REFINED


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


POLISH_FTOL = 1e-5
"""The polish on the mid-size copy ends once a step lowers its cost by less than this fraction, as the last
solve on the fitted samples does (``fitting.FINAL_FTOL``): cheaper than running to ``polish_tol``, and the
RMSEs stay within 3e-5 relative of that on the knee dry run (docs/analysis.md)."""


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
    polish_ftol: relative cost decrease that ends the polish on the mid-size copy (``None``: ``polish_tol``);
        ``POLISH_FTOL`` by default, the early stop of the last solve that follows it (tolerance:
        docs/analysis.md, tests/models/test_bouc_wen_same_numbers.py).
    final_solve: False ends the refined scheme's fit with the polish on a mid-size copy that keeps the
        angle's turning points (:func:`.copies.turning_point_copy`) instead of a last solve on the fitted
        samples: the held-out fits of :func:`.cross_validate` (tolerance in docs/analysis.md).
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
