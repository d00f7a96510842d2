"""The protocol's `processing` and `fits` sections as the analysis's settings."""

from __future__ import annotations

from ..analysis.pipeline import ProcessingSettings
from ..analysis.service import BoucWenSettings
from .loaded import LoadedProtocol


def processing_settings(loaded: LoadedProtocol) -> ProcessingSettings:
    proc = loaded.protocol.processing
    return ProcessingSettings(
        transition_tolerance_deg=proc.transition.tolerance_deg,
        transition_points=proc.transition.points,
        filter_kind=proc.filter.kind,
        filter_order=proc.filter.order,
        filter_cutoff=proc.filter.cutoff,
        chebyshev_ripple_db=proc.filter.ripple_db,
        subtraction=proc.subtraction,
        centring="trial_mean" if proc.centre_for_fit else "none",
    )


def bouc_wen_settings(loaded: LoadedProtocol) -> BoucWenSettings:
    """The protocol's `fits.bouc_wen` as the analysis's settings (whether it runs is `.enabled` there)."""
    spec = loaded.protocol.fits.bouc_wen
    return BoucWenSettings(
        starts=spec.starts,
        cross_validate=spec.cross_validate,
        backbone=spec.backbone,
        backbone_degree=spec.backbone_degree,
    )


def element_fit_enabled(loaded: LoadedProtocol) -> bool:
    """Whether the device's elastic elements are fitted (the protocol's element fit, `fits.spring`)."""
    fits = loaded.protocol.fits
    enabled = getattr(fits, "elements", getattr(fits, "spring", None))
    return bool(enabled and enabled.enabled)
