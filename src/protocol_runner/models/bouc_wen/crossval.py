"""Leave-one-trial-out cross-validation of the Bouc-Wen fit: the trial is the unit (issue 15 item 5)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .backbone import AnyBackbone, BackboneFactory, fit_backbone, hysteretic_part
from .fitting import _fit_segments, _validate_segments
from .params import BoucWenParams
from .problem import DEFAULT_BOUNDS, DIVERGENCE_FACTOR, BoucWenBounds, evaluate
from .schemes import REFINED
from .threads import blas_single_threaded

CV_FINAL_FTOL = 1e-4  # a held-out fit's last solve ends once a step lowers its cost by less than this
# fraction: its held-out error then agrees with a solve run to 1e-8 within about 1e-4 (tested)


@blas_single_threaded
def cross_validate(
    segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    starts: int = 4,
    bounds: BoucWenBounds = DEFAULT_BOUNDS,
    seed: int = 0,
    max_samples_per_trial: int | None = 8000,
    initial: BoucWenParams | None = None,
    scheme: str = REFINED,
    backbone_degree: int | None = None,
    backbone_factory: BackboneFactory | None = None,
) -> list[float]:
    """Leave-one-trial-out RMSE (N*m): for each trial, fit the others and predict the held-out trial from
    its own first torque.  Needs at least two trials.

    Each held-out fit is a multi-start fit of its own (the Figure 56 and equation-error starts computed on
    the other trials, plus ``starts`` quasi-random ones): nothing computed from the held-out trial enters
    it.  A parameter the other trials cannot determine (e.g. a Table 4 phase only the held-out trial
    visits) then stays where the other trials leave it, and the held-out error shows it.

    backbone_degree: as in :func:`.fit_trials`; each held-out fit then fits its backbone on the other
        trials too, and the held-out prediction is ``g(angle) + z``.
    backbone_factory: as in :func:`.fit_trials`; called with the other trials' indices for each held-out
        fit (a factory that fits ``g`` fits it on those trials only).
    initial: an extra start for every held-out fit.  It must not have been fitted on the held-out trial
        (a fit on all trials would carry the held-out trial into its own test); ``None`` by default.
    """
    checked = _validate_segments(segments)
    if len(checked) < 2:
        raise InvalidInput(f"cross-validation needs at least 2 trials, got {len(checked)}")
    errors: list[float] = []
    for k, (x, y) in enumerate(checked):
        others = [s for j, s in enumerate(checked) if j != k]
        backbone: AnyBackbone | None = None
        if backbone_degree is not None:
            backbone = fit_backbone(others, backbone_degree)
        elif backbone_factory is not None:
            backbone = backbone_factory([j for j in range(len(checked)) if j != k])
        if backbone is not None:
            others = hysteretic_part(others, backbone)
            x, y = hysteretic_part([(x, y)], backbone)[0]
        result = _fit_segments(
            others,
            starts=starts,
            initial=initial,
            data_starts=True,
            bounds=bounds,
            seed=seed,
            max_samples_per_trial=max_samples_per_trial,
            polish=1,
            polish_tol=1e-8,
            scheme=scheme,
            final_ftol=CV_FINAL_FTOL,
        )
        scale = max(float(np.max(np.abs(y))), max(float(np.max(np.abs(yy))) for _, yy in others))
        rmse, _, _, _ = evaluate([(x, y)], result.params, DIVERGENCE_FACTOR * scale, scheme)
        errors.append(rmse)
    return errors
