"""The Bouc-Wen backbone from the device's declared elastic elements.

``torque = g(angle) + z`` (thesis Eq 19-23 for ``z``): with ``backbone: elements`` the elastic part ``g``
is the sum of the device's angle-only torques (springs, bungees, masses' gravity; thesis §6.1) with the
parameters the element fit estimates from the loops' midline (:mod:`.element_fit`), and the Bouc-Wen
state describes what is left.  ``g`` is held fixed during the Bouc-Wen fit.

The element fit is refitted on exactly the trials a Bouc-Wen fit may use (the factory takes their
indices), so a trial held out by cross-validation never enters its own backbone; the element fit is a
few small least-squares solves on the branch midline, cheap beside the Bouc-Wen fit.

The Bouc-Wen fit works on loops centred per trial on (0, 0) (thesis §6.2.3 note), while the elements
are functions of the absolute angle.  In centred coordinates ``g(x) = G(x + a) - c`` where ``a`` is the
mean of the fitted trials' mean angles and ``c`` the mean of ``G`` over their samples, so ``g`` is
centred like the torque.  Trials of one configuration repeat the same motion, so their mean angles agree
closely; a difference ``da`` between a trial's mean angle and ``a`` shifts its ``g`` by about
``G' da``.  A device with no elastic element, or an element fit that is not applicable, gives ``g = 0``
(the thesis form torque = z) and the reason is recorded with the fit.
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
    on those trials' processed (uncentred) loops, as ``g`` of the centred angle (module docstring).

    trials: each trial's processed ``(angle_deg, brace_torque_nm)``, in the order of the fit's segments.
    device: the configuration's device (``models.elements.Element`` or ElementSetting-like objects)."""
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
