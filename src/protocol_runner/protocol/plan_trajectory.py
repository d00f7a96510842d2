"""What a trial commands, as the plan records it: the `Trajectory` (JSON shape of the plan contract) and
how a configuration's, or the calibration step's, is derived from the protocol.

`build_trajectory` turns a named `TrajectorySpec` (protocol/trajectory_specs.py) and the values of its bound
fields into a `Trajectory`; its JSON is {"profile": kind, "name": name, the kind's fields resolved,
"duration_s"} (a sinusoid also keeps mean_deg, amplitude_deg and period_s; a file keeps `source`, the
file as written, plus the angle `column` read and its `origin`). `protocol/sampling.py` samples any of
them. `trajectory_for` and `calibration_trajectory` are the schema_version 1 path.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InvalidInput
from ..hardware.safety import SafetyLimits
from .levels import Settings
from .loaded import LoadedProtocol
from .paths import OutsideFolder, confined_path
from .schema import ConfigurationSpec, Protocol
from .trajectories import load_trajectory_file, sinusoid_period_s, triangle_period_s
from .trajectory_specs import (
    BINDABLE_FIELDS,
    FileSpec,
    HoldSpec,
    IdentificationSpec,
    RampedStepSpec,
    SinusoidSpec,
    TrajectorySpec,
    TriangleSpec,
)

ParamValue = float | str | tuple[float, ...]
Quantity = float | tuple[float, ...]


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


def build_trajectory(
    name: str,
    spec: TrajectorySpec,
    values: Mapping[str, Quantity],
    base_dir: Path,
    *,
    joint: str | None = None,
    limits: SafetyLimits | None = None,
) -> Trajectory:
    """The trajectory `name` commands, with each bound field of `spec` taking its value from `values`
    (field -> the resolved factor quantity). A file is read from `base_dir` (its angle column: `joint`'s,
    else `angle_deg`); a triangle without `corner_accel_deg_s2` turns at `limits.max_accel_deg_s2`.
    `InvalidInput` names the trajectory and the field."""
    fields = _resolve(name, spec, values)
    where = f"trajectory {name!r}"
    if isinstance(spec, SinusoidSpec):
        lo, hi = _pair(fields["range_deg"])
        speed = _num(fields["speed_deg_s"])
        amplitude = (hi - lo) / 2.0
        period = sinusoid_period_s(amplitude, speed)  # Eq 25
        return Trajectory(
            profile="sinusoid",
            name=name,
            mean_deg=(hi + lo) / 2.0,
            amplitude_deg=amplitude,
            period_s=period,
            params=(("range_deg", (lo, hi)), ("speed_deg_s", speed), ("periods", spec.periods)),
            duration_s=spec.periods * period,
        )
    if isinstance(spec, TriangleSpec):
        lo, hi = _pair(fields["range_deg"])
        speed = _num(fields["speed_deg_s"])
        given = fields.get("corner_accel_deg_s2")
        if given is not None:
            accel = _num(given)
        elif limits is not None:
            accel = limits.max_accel_deg_s2
        else:
            raise InvalidInput(
                f"{where}: corner_accel_deg_s2 is not given and no joint acceleration limit is known"
            )
        if hi - lo < speed * speed / accel:
            raise InvalidInput(
                f"{where}: speed_deg_s {speed:g} deg/s cannot be reached within range_deg [{lo:g}, {hi:g}] "
                f"with corners at {accel:g} deg/s² (it needs a range of at least speed²/accel = "
                f"{speed * speed / accel:.4g} deg)"
            )
        return Trajectory(
            profile="triangle",
            name=name,
            params=(
                ("range_deg", (lo, hi)),
                ("speed_deg_s", speed),
                ("cycles", spec.cycles),
                ("corner_accel_deg_s2", accel),
            ),
            duration_s=spec.cycles * triangle_period_s(hi - lo, speed, accel),
        )
    if isinstance(spec, FileSpec):
        try:
            path = confined_path(base_dir, spec.file)
        except OutsideFolder as exc:
            raise InvalidInput(f"{where}: file: {exc}") from None
        data = load_trajectory_file(path, joint)
        origin = spec.origin or (data.header.splitlines()[0] if data.header else "")
        if not origin:
            raise InvalidInput(
                f"{where}: file {spec.file}: state where the motion comes from, in comment lines (#) before "
                "the column row or as `origin:` in the protocol"
            )
        return Trajectory(
            profile="file",
            name=name,
            source=spec.file,
            params=(("column", data.column), ("origin", origin)),
            duration_s=data.duration_s,
        )
    if isinstance(spec, IdentificationSpec):
        lo, hi = _pair(fields["range_deg"])
        return Trajectory(
            profile="identification",
            name=name,
            params=(
                ("min_deg", lo),
                ("max_deg", hi),
                ("repetition_s", spec.repetition_s),
                ("initial_period_s", spec.initial_period_s),
                ("final_period_s", spec.final_period_s),
            ),
            duration_s=spec.total_s,
        )
    if isinstance(spec, RampedStepSpec):
        return Trajectory(
            profile="ramped_step",
            name=name,
            params=(
                ("from_deg", _num(fields["from_deg"])),
                ("step_deg", _num(fields["step_deg"])),
                ("settle_s", spec.settle_s),
                ("ramp_s", spec.ramp_s),
                ("hold_s", spec.hold_s),
            ),
            duration_s=spec.settle_s + spec.ramp_s + spec.hold_s,
        )
    assert isinstance(spec, HoldSpec)
    return Trajectory(
        profile="hold",
        name=name,
        params=(("angle_deg", _num(fields["angle_deg"])),),
        duration_s=spec.duration_s,
    )


def _resolve(name: str, spec: TrajectorySpec, values: Mapping[str, Quantity]) -> dict[str, Quantity | None]:
    """Each bindable field's value: its constant, or the resolved value of its binding (checked)."""
    out: dict[str, Quantity | None] = {}
    for field in BINDABLE_FIELDS[spec.kind]:
        written = getattr(spec, field)
        if not isinstance(written, str):
            out[field] = written
            continue
        if field not in values:
            raise InvalidInput(
                f"trajectory {name!r}: {field} is bound to {written} but no value was given for it"
            )
        value = values[field]
        what = f"trajectory {name!r}: {field} (bound to {written})"
        if field == "range_deg":
            if not (isinstance(value, tuple) and len(value) == 2 and value[0] < value[1]):
                raise InvalidInput(f"{what} needs a range [low, high] with low < high, got {value!r}")
        elif not isinstance(value, float | int) or isinstance(value, bool):
            raise InvalidInput(f"{what} needs a number, got {value!r}")
        elif field in ("speed_deg_s", "corner_accel_deg_s2") and not value > 0:
            raise InvalidInput(f"{what} must be greater than 0, got {value:g}")
        out[field] = value
    return out


def _pair(value: Quantity | None) -> tuple[float, float]:
    assert isinstance(value, tuple) and len(value) == 2
    return float(value[0]), float(value[1])


def _num(value: Quantity | None) -> float:
    assert isinstance(value, float | int)
    return float(value)


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
