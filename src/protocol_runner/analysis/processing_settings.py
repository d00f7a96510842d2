"""Every choice of the processing (thesis §3.2, §3.3.1, §4.4): a plain dataclass that the session and the
protocol loader import without loading the processing itself (scipy's signal and optimisation packages)."""

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
CHOICES: dict[str, tuple[str, ...]] = {  # the settings that name one of a few methods, and their names
    "command_resampling": ("hold", "linear"),
    "filter_kind": FILTER_KINDS,
    "subtraction": ("equal_angle", "equal_time"),
    "outside": ("clip", "nan"),
    "cycle_reference": ("mean", "linear"),
    "centring": ("trial_mean", "none"),
    "element_fit_target": ("branch_mean", "all_samples"),
}


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

        for name in ("transition_tolerance_deg", "chebyshev_ripple_db", "bin_width_deg", "reversal_deg"):
            if not getattr(self, name) > 0:
                raise bad(name, "must be positive")
        for name, allowed in CHOICES.items():
            if getattr(self, name) not in allowed:
                raise bad(name, "must be " + " or ".join(map(repr, allowed)))
        if isinstance(self.transition_points, bool) or self.transition_points < 1:
            raise bad("transition_points", "must be a whole number >= 1")
        if (
            isinstance(self.filter_order, bool)
            or not isinstance(self.filter_order, int | np.integer)
            or self.filter_order < 1
        ):
            raise bad("filter_order", "must be a whole number >= 1")
        if not 0 < self.filter_cutoff < 1:
            raise bad("filter_cutoff", "must be a fraction of the Nyquist frequency strictly between 0 and 1")
        if self.cycle_hysteresis_deg is not None and not self.cycle_hysteresis_deg >= 0:
            raise bad("cycle_hysteresis_deg", "must be >= 0 (or None for automatic)")

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
