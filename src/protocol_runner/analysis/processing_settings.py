"""Every choice of the processing (thesis §3.2, §3.3.1, §4.4), in a module of its own: a plain dataclass
that whoever hands settings to the processing (the session, the protocol loader) imports without loading
the processing itself (`pipeline`: scipy's signal and optimisation packages)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from protocol_runner.analysis.branches import Outside
from protocol_runner.analysis.cycles import Reference
from protocol_runner.analysis.transition import Resampling
from protocol_runner.errors import InvalidInput

if TYPE_CHECKING:
    from protocol_runner.analysis.element_fit import FitTarget

FilterKind = Literal["butterworth", "chebyshev"]
FILTER_KINDS: tuple[str, ...] = ("butterworth", "chebyshev")
Subtraction = Literal["equal_angle", "equal_time"]
Centring = Literal["trial_mean", "none"]


@dataclass(frozen=True)
class ProcessingSettings:
    """Every choice of the processing, with the thesis's values as defaults (§3.2, §3.3.1, §4.4).

    filter_cutoff is a fraction of the Nyquist frequency (thesis: 0.1); chebyshev_ripple_db is used only
    with filter_kind="chebyshev". bin_width_deg and reversal_deg tune the equal-angle subtraction's
    per-branch curves; outside says what brace-on angles beyond the brace-off range get ("clip" = the
    nearest covered angle's torque). cycle_hysteresis_deg=None uses 10 % of the angle range.
    """

    transition_tolerance_deg: float = 5.0
    transition_points: int = 3
    command_resampling: Resampling = "hold"
    filter_kind: FilterKind = "butterworth"
    filter_order: int = 10
    filter_cutoff: float = 0.1
    chebyshev_ripple_db: float = 0.5
    subtraction: Subtraction = "equal_angle"
    bin_width_deg: float = 0.5
    reversal_deg: float = 1.0
    outside: Outside = "clip"
    cycle_reference: Reference = "mean"
    cycle_hysteresis_deg: float | None = None
    centring: Centring = "trial_mean"
    element_fit_target: FitTarget = "branch_mean"

    def __post_init__(self) -> None:
        def bad(field_name: str, why: str) -> InvalidInput:
            return InvalidInput(f"processing settings: {field_name} {why}, got {getattr(self, field_name)!r}")

        if not self.transition_tolerance_deg > 0:
            raise bad("transition_tolerance_deg", "must be positive")
        if isinstance(self.transition_points, bool) or self.transition_points < 1:
            raise bad("transition_points", "must be a whole number >= 1")
        if self.command_resampling not in ("hold", "linear"):
            raise bad("command_resampling", "must be 'hold' or 'linear'")
        if self.filter_kind not in FILTER_KINDS:
            raise bad("filter_kind", f"must be one of {', '.join(FILTER_KINDS)}")
        if (
            isinstance(self.filter_order, bool)
            or not isinstance(self.filter_order, int | np.integer)
            or self.filter_order < 1
        ):
            raise bad("filter_order", "must be a whole number >= 1")
        if not 0 < self.filter_cutoff < 1:
            raise bad("filter_cutoff", "must be a fraction of the Nyquist frequency strictly between 0 and 1")
        if not self.chebyshev_ripple_db > 0:
            raise bad("chebyshev_ripple_db", "must be positive")
        if self.subtraction not in ("equal_angle", "equal_time"):
            raise bad("subtraction", "must be 'equal_angle' or 'equal_time'")
        if not self.bin_width_deg > 0:
            raise bad("bin_width_deg", "must be positive")
        if not self.reversal_deg > 0:
            raise bad("reversal_deg", "must be positive")
        if self.outside not in ("clip", "nan"):
            raise bad("outside", "must be 'clip' or 'nan'")
        if self.cycle_reference not in ("mean", "linear"):
            raise bad("cycle_reference", "must be 'mean' or 'linear'")
        if self.cycle_hysteresis_deg is not None and not self.cycle_hysteresis_deg >= 0:
            raise bad("cycle_hysteresis_deg", "must be >= 0 (or None for automatic)")
        if self.centring not in ("trial_mean", "none"):
            raise bad("centring", "must be 'trial_mean' or 'none'")
        if self.element_fit_target not in ("branch_mean", "all_samples"):
            raise bad("element_fit_target", "must be 'branch_mean' or 'all_samples'")

    def filter_description(self, sample_rate_hz: float | None = None) -> dict[str, Any]:
        """The filter settings as a plain dict (for the archive's `filter` JSON attribute); with the input
        rate it filtered at, also the cut-off in Hz (`cutoff` is the fraction of the Nyquist frequency)."""
        out: dict[str, Any] = {
            "kind": self.filter_kind,
            "order": self.filter_order,
            "cutoff": self.filter_cutoff,
        }
        if sample_rate_hz is not None:
            out["cutoff_hz"] = self.filter_cutoff * sample_rate_hz / 2.0
            out["sample_rate_hz"] = sample_rate_hz
        if self.filter_kind == "chebyshev":
            out["ripple_db"] = self.chebyshev_ripple_db
        out["zero_phase"] = True
        return out

    def as_dict(self) -> dict[str, Any]:
        """All settings as a plain dict (JSON-serialisable)."""
        return asdict(self)
