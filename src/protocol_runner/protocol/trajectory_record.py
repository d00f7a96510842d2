"""What a trial commands, as the plan records it: the `Trajectory` (JSON shape of the plan contract).

Its `profile` is the trajectory kind (protocol/trajectory_specs.py), whose model built it and samples it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

ParamValue = float | str | tuple[float, ...]


@dataclass(frozen=True)
class Trajectory:
    """What to command during a trial (JSON shape of the plan contract)."""

    profile: str
    duration_s: float
    mean_deg: float | None = None
    amplitude_deg: float | None = None
    period_s: float | None = None
    source: str | None = None
    params: tuple[tuple[str, ParamValue], ...] = ()
    name: str | None = None  # the protocol's name for it (build_trajectory)

    def param(self, field: str) -> ParamValue:
        """The value of a kind field (`KeyError` if it has none)."""
        return dict(self.params)[field]

    def number(self, field: str) -> float:
        """The value of a numeric kind field (`KeyError` if it has none, `TypeError` if not a number)."""
        value = self.param(field)
        if isinstance(value, str | tuple):
            raise TypeError(f"trajectory field {field} is not a number: {value!r}")
        return float(value)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"profile": self.profile}
        if self.name is not None:
            out["name"] = self.name
        if self.profile == "sinusoid":
            out.update(mean_deg=self.mean_deg, amplitude_deg=self.amplitude_deg, period_s=self.period_s)
        if self.source is not None:
            out["source"] = self.source
        out.update({k: list(v) if isinstance(v, tuple) else v for k, v in self.params})
        out["duration_s"] = self.duration_s
        return out
