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
    final_ftol: relative cost decrease that ends the last solve after a polish on the mid-size copy
        (``None``: ``fitting.FINAL_FTOL``).
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
    final_ftol: float | None = None
