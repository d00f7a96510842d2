"""What a trial commands, as the plan records it: the `Trajectory` (JSON shape of the plan contract) and
how a configuration's, or the calibration step's, is derived from the protocol."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .levels import Settings
from .loaded import LoadedProtocol
from .schema import ConfigurationSpec, Protocol
from .trajectories import load_trajectory_file, sinusoid_period_s


@dataclass(frozen=True)
class Trajectory:
    """What to command during a trial (JSON shape of the plan contract)."""

    profile: str
    duration_s: float
    mean_deg: float | None = None
    amplitude_deg: float | None = None
    period_s: float | None = None
    source: str | None = None
    params: tuple[tuple[str, float | str], ...] = ()

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"profile": self.profile}
        if self.profile == "sinusoid":
            out.update(mean_deg=self.mean_deg, amplitude_deg=self.amplitude_deg, period_s=self.period_s)
        if self.source is not None:
            out["source"] = self.source
        out.update(dict(self.params))
        out["duration_s"] = self.duration_s
        return out


def trajectory_for(
    p: Protocol, loaded: LoadedProtocol | None, cfg: ConfigurationSpec, settings: Settings
) -> Trajectory:
    if cfg.profile == "sinusoid":
        lo, hi = settings.robot_rom_deg
        amplitude = (hi - lo) / 2.0
        period = sinusoid_period_s(amplitude, settings.speed_deg_s)
        return Trajectory(
            profile="sinusoid",
            mean_deg=(hi + lo) / 2.0,
            amplitude_deg=amplitude,
            period_s=period,
            duration_s=p.trajectories.sinusoid.periods * period,
        )
    if cfg.profile == "human":
        assert cfg.trajectory is not None
        spec = p.trajectories.human[cfg.trajectory]
        duration = 0.0
        if loaded is not None:
            duration = load_trajectory_file(loaded.base_dir / spec.file).duration_s
        return Trajectory(
            profile="human", source=spec.file, duration_s=duration, params=(("name", cfg.trajectory),)
        )
    ident = p.trajectories.identification
    assert ident is not None
    return Trajectory(
        profile="identification",
        duration_s=ident.total_s,
        params=(
            ("min_deg", ident.range_deg[0]),
            ("max_deg", ident.range_deg[1]),
            ("repetition_s", ident.repetition_s),
            ("initial_period_s", ident.initial_period_s),
            ("final_period_s", ident.final_period_s),
        ),
    )


def calibration_trajectory(p: Protocol) -> Trajectory:
    s = p.trajectories.calibration_step
    return Trajectory(
        profile="step",
        duration_s=s.settle_s + s.ramp_s + s.hold_s,
        params=(
            ("from_deg", s.from_deg),
            ("step_deg", s.step_deg),
            ("settle_s", s.settle_s),
            ("ramp_s", s.ramp_s),
        ),
    )
