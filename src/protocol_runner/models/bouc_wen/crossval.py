"""Leave-one-trial-out cross-validation of the Bouc-Wen fit: the trial is the unit."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Unpack

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .backbone import BackboneFactory, hysteretic_part
from .fitting import _validate_segments, backbone_for, fitted_params
from .options import FitKeywords, FitOptions
from .problem import DIVERGENCE_FACTOR, evaluate
from .threads import blas_single_threaded

HELD_OUT_FTOL = 1e-5  # a held-out fit's polish (its last solve) ends once a step lowers its cost by less
# than this fraction (tolerance of the held-out errors: docs/analysis.md, tests/models/test_bouc_wen_same_numbers.py)


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

    Each held-out fit is a multi-start fit of its own (the Figure 56 and equation-error starts computed on
    the other trials, plus ``starts`` quasi-random ones; options as in :func:`.fit_trials`): nothing
    computed from the held-out trial enters it.  It ends with its polish (to a relative cost change of
    ``HELD_OUT_FTOL``) on the mid-size copy of the other trials that keeps their angle's turning points
    (:func:`.copies.turning_point_copy`), not with a last solve on the fitted samples: its held-out error
    is within 1 % of the full procedure's (docs/analysis.md), at about a third of the cost.  A parameter
    the other trials cannot determine (e.g. a Table 4 phase only the held-out trial visits) then stays
    where the other trials leave it, and the held-out error shows it.

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
