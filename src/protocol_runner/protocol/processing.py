"""The protocol's `processing` section as the analysis's settings."""

from __future__ import annotations

from ..analysis.pipeline import ProcessingSettings
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
