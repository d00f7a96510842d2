"""The Bouc-Wen fit of a configuration's centred loops (thesis §6.2), from plain arrays.

Used by the fit step and by `--reprocess`, so both give the same numbers.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..models.bouc_wen.backbone import zero_backbone
from ..models.bouc_wen.records import BoucWenFit
from .bouc_wen_fit import fit_configuration
from .centring import centre
from .elastic_backbone import elements_backbone_factory


def centred_loop(angle_deg: np.ndarray, torque_nm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A processed trial centred on (0, 0) (§6.2.3 note), undefined samples dropped."""
    keep = np.isfinite(torque_nm)
    loop = centre(angle_deg[keep], torque_nm[keep])
    return loop.angle_deg, loop.torque_nm


def fit_loops(
    segments: list[tuple[np.ndarray, np.ndarray]],
    *,
    starts: int,
    cross_validated: bool,
    backbone_degree: int | None,
    elements: tuple[Sequence[tuple[np.ndarray, np.ndarray]], Sequence[object] | None] | None = None,
) -> tuple[BoucWenFit, list[float]]:
    """The joint fit over a configuration's trials (with intervals), and leave-one-trial-out RMSEs when
    asked and possible (:func:`.bouc_wen_fit.fit_configuration`); ``backbone_degree`` None is the thesis
    form torque = z.  ``elements``: the backbone from the device's elastic elements instead
    (:mod:`.elastic_backbone`): each trial's processed, uncentred ``(angle_deg, brace_torque_nm)`` in the
    order of ``segments``, and the device (None when the element fit is disabled: then ``g = 0``)."""
    factory = None
    if elements is not None:
        raw, device = elements
        factory = (
            elements_backbone_factory(raw, device)
            if device is not None
            else (lambda _: zero_backbone("not applicable: the element fit is disabled"))
        )
        backbone_degree = None
    return fit_configuration(
        segments,
        starts=starts,
        cross_validate_trials=cross_validated,
        backbone_degree=backbone_degree,
        backbone_factory=factory,
    )
