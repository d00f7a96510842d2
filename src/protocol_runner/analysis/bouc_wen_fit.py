"""Fit one configuration's centred trials with the generalised Bouc-Wen model, with the evidence a modeller
needs to trust it (docs/analysis.md §9): the fit and its convergence record, leave-one-trial-out errors,
parameter intervals, and the model's loop energy beside the data's. Pure: the fit step and ``--reprocess``
both fit through :func:`fit_loops`, so they give the same numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..models.bouc_wen.backbone import BackboneFactory, zero_backbone
from ..models.bouc_wen.fitting import cross_validate, fit_trials
from ..models.bouc_wen.identifiability import identify
from ..models.bouc_wen.params import BoucWenParams
from ..models.bouc_wen.records import BoucWenFit
from ..models.bouc_wen.simulation import simulate_trials
from .centring import centre
from .elastic_backbone import elements_backbone_factory
from .energy import energy_per_cycle

Segment = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class LoopEnergy:
    """Mean energy lost per complete cycle (J) by the model torque and by the data over the same angle
    samples (thesis §5.7, Eq 10-12); NaN when the trials hold no complete cycle."""

    model_j: float
    data_j: float

    @property
    def model_dissipates(self) -> bool:
        """The physical constraint: the model loses energy wherever the data do (True when the data do
        not, or when there is no complete cycle to tell)."""
        if not (math.isfinite(self.data_j) and self.data_j > 0.0):
            return True
        return math.isfinite(self.model_j) and self.model_j > 0.0


def fit_configuration(
    segments: Sequence[Segment],
    *,
    starts: int = 8,
    cross_validate_trials: bool = True,
    backbone_degree: int | None = 9,
    backbone_factory: BackboneFactory | None = None,
) -> tuple[BoucWenFit, list[float]]:
    """The joint fit over a configuration's trials with its intervals and weak-identification mark, and the
    leave-one-trial-out RMSEs (N*m) when asked and there are at least two trials.  Each held-out fit is
    fitted from scratch on the other trials (nothing from the held-out trial enters it, backbone included).

    backbone_degree: ``torque = g(angle) + z`` with ``g`` a polynomial of this degree (the loops' midline,
    :mod:`..models.bouc_wen.backbone`); ``None`` is the thesis form ``torque = z``.
    backbone_factory: ``g`` given and held fixed instead (e.g. the device's elastic elements,
    :func:`.elastic_backbone.elements_backbone_factory`, refitted on the other trials in each held-out
    fit); then ``backbone_degree`` must be None."""
    result = identify(
        segments,
        fit_trials(
            segments, starts=starts, backbone_degree=backbone_degree, backbone_factory=backbone_factory
        ),
    )
    cv: list[float] = []
    if cross_validate_trials and len(segments) >= 2:
        cv = cross_validate(
            segments,
            starts=max(1, starts // 4),
            backbone_degree=backbone_degree,
            backbone_factory=backbone_factory,
        )
    return result, cv


def model_torques(segments: Sequence[Segment], fit: BoucWenFit | BoucWenParams) -> list[np.ndarray]:
    """The model's torque on every sample of each trial (backbone plus Bouc-Wen state when the fit has a
    backbone), the state started so that the torque starts at the trial's first torque."""
    params = fit if isinstance(fit, BoucWenParams) else fit.params
    backbone = None if isinstance(fit, BoucWenParams) else fit.backbone
    if backbone is None:
        return simulate_trials([x for x, _ in segments], params, [float(y[0]) for _, y in segments])
    gs = [backbone(x) for x, _ in segments]
    z0s = [float(y[0] - g[0]) for (_, y), g in zip(segments, gs, strict=True)]
    zs = simulate_trials([x for x, _ in segments], params, z0s)  # every trial in one call
    return [g + z for g, z in zip(gs, zs, strict=True)]


def loop_energy(segments: Sequence[Segment], models: Sequence[np.ndarray]) -> LoopEnergy:
    """Mean loop energy per complete cycle of the model torques and of the data torques."""
    model: list[np.ndarray] = []
    data: list[np.ndarray] = []
    for (x, y), z in zip(segments, models, strict=True):
        data.append(energy_per_cycle(x, y))
        finite = bool(np.all(np.isfinite(z)))  # a diverged model has no loop
        model.append(energy_per_cycle(x, z) if finite else np.full(data[-1].shape, math.nan))
    d = np.concatenate(data) if data else np.empty(0)
    m = np.concatenate(model) if model else np.empty(0)
    return LoopEnergy(
        model_j=float(np.mean(m)) if m.size else math.nan,
        data_j=float(np.mean(d)) if d.size else math.nan,
    )


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
