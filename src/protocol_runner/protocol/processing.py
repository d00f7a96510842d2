"""The protocol's `processing` and `fits` sections as the analysis's settings."""

from __future__ import annotations

from functools import reduce
from typing import TYPE_CHECKING, Any

from ..analysis.processing_settings import ProcessingSettings
from .loaded import LoadedProtocol

if TYPE_CHECKING:
    from ..analysis.service import BoucWenSettings

#: Each ProcessingSettings field the protocol sets <- where its `processing` section holds it.
SECTION_PATHS: dict[str, tuple[str, ...]] = {
    "transition_tolerance_deg": ("transition", "tolerance_deg"),
    "transition_points": ("transition", "points"),
    "filter_kind": ("filter", "kind"),
    "filter_order": ("filter", "order"),
    "filter_cutoff": ("filter", "cutoff"),
    "chebyshev_ripple_db": ("filter", "ripple_db"),
    "subtraction": ("subtraction",),
}


def processing_settings(loaded: LoadedProtocol) -> ProcessingSettings:
    """The protocol's `processing` section as the analysis's settings (the rest keep the thesis defaults;
    ProcessingSettings checks every value)."""
    proc = loaded.protocol.processing
    values: dict[str, Any] = {name: reduce(getattr, path, proc) for name, path in SECTION_PATHS.items()}
    return ProcessingSettings(**values, centring="trial_mean" if proc.centre_for_fit else "none")


def bouc_wen_settings(loaded: LoadedProtocol) -> BoucWenSettings:
    """The protocol's `fits.bouc_wen` as the analysis's settings (whether it runs is `.enabled` there)."""
    from ..analysis.service import BoucWenSettings  # here: only the fits load the model and its solver

    spec = loaded.protocol.fits.bouc_wen
    return BoucWenSettings(
        starts=spec.starts,
        cross_validate=spec.cross_validate,
        backbone=spec.backbone,
        backbone_degree=spec.backbone_degree,
    )


def element_fit_enabled(loaded: LoadedProtocol) -> bool:
    """Whether the device's elastic elements are fitted (the protocol's element fit, `fits.spring`)."""
    return loaded.protocol.fits.spring.enabled
