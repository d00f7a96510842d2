"""The Bouc-Wen backbone from the device's declared elastic elements (``backbone: elements``; docs/analysis.md
§9 gives the reasons and the tests).

``torque = g(angle) + z``: ``g`` is the sum of the device's angle-only torques with the parameters the
element fit estimates from the loops' midline (:mod:`.element_fit`), refitted on exactly the trials a fit
may use (a held-out trial never enters its own backbone) and held fixed during the Bouc-Wen fit. The loops
are centred per trial, the elements are functions of the absolute angle: ``g(x) = G(x + a) - c`` with ``a``
the mean of the fitted trials' mean angles and ``c`` the mean of ``G`` over their samples. No elastic
element, or an element fit that is not applicable, gives ``g = 0`` with the reason recorded.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..models.bouc_wen.backbone import BackboneFactory, FixedBackbone, zero_backbone
from .element_fit import fit_elements, model_torque_nm
from .validation import AnalysisError

Trial = tuple[np.ndarray, np.ndarray]


def _finite(trial: Trial) -> Trial:
    angle = np.asarray(trial[0], dtype=np.float64)
    torque = np.asarray(trial[1], dtype=np.float64)
    keep = np.isfinite(torque)  # as the centred loops (analysis.bouc_wen_fit.centred_loop)
    return angle[keep], torque[keep]


@dataclass(frozen=True)
class ShiftedElements:
    """The fitted elements' torque as ``g`` of the centred angle: ``g(x) = T(x + offset_deg) - offset_nm``
    (a class, not a closure, so that a fit made in a worker process can be sent back)."""

    elements: tuple[Any, ...]
    offset_deg: float
    offset_nm: float

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(model_torque_nm(self.elements, x + self.offset_deg) - self.offset_nm)


def elements_backbone_factory(trials: Sequence[Trial], device: Sequence[object]) -> BackboneFactory:
    """A factory of the elements backbone: given the indices of the trials a fit may use, the element fit
    on those trials' processed, uncentred ``(angle_deg, brace_torque_nm)`` (``trials``, in the order of the
    fit's segments) as ``g`` of the centred angle. ``device``: ``Element`` or ElementSetting-like objects."""
    loops = [_finite(t) for t in trials]

    def factory(indices: Sequence[int]) -> FixedBackbone:
        chosen = [loops[k] for k in indices]
        if not chosen:
            return zero_backbone("not applicable: no trial to fit the elements on")
        angle = np.concatenate([a for a, _ in chosen])
        torque = np.concatenate([t for _, t in chosen])
        try:
            fit = fit_elements(angle, torque, device)
        except AnalysisError as exc:
            return zero_backbone(f"not applicable: {exc}")
        if not fit.applicable:
            return zero_backbone(fit.reason)
        elements = fit.elements
        offset_deg = float(np.mean([np.mean(a) for a, _ in chosen]))
        offset_nm = float(np.mean([np.mean(model_torque_nm(elements, a)) for a, _ in chosen]))
        fitted = ", ".join(f"{e}.{p} = {v:.6g}" for e, p, v in fit.fitted) or "no free parameter"
        return FixedBackbone(
            torque_nm=ShiftedElements(tuple(elements), offset_deg, offset_nm),
            kind="elements",
            note=f"device elements, {fit.reason} ({fitted}); centred at {offset_deg:.6g} deg",
        )

    return factory
