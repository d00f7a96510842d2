"""The protocol's trajectory kinds (`trajectories:` of a schema_version 2 protocol), and their registry.

One pydantic model per kind, told apart by `kind`, declares everything about the kind (docs/architecture.md
"a trajectory kind"); `TRAJECTORY_KINDS` registers them. A field typed `float | str` (or `RangePair | str`)
may be BOUND to a factor quantity: a string `"<factor>.<quantity>"` takes the value of that quantity in each
configuration's level (`trajectory_bindings` lists them; `build_trajectory` takes their resolved values).
`per_joint` is not a motion of its own: it gives each joint of a multi-joint protocol one of the kinds.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, ClassVar, Generic, Literal, Protocol, TypeVar, get_args

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, GetCoreSchemaHandler, field_validator
from pydantic_core import CoreSchema, core_schema

from ..errors import InvalidInput
from ..hardware.safety import SafetyLimits
from .paths import OutsideFolder, confined_path
from .trajectories import (
    calibration_step_deg,
    calibration_step_peak_accel_deg_s2,
    calibration_step_peak_speed_deg_s,
    hold_deg,
    identification_deg,
    load_trajectory_file,
    sinusoid_deg,
    sinusoid_peak_accel_deg_s2,
    sinusoid_period_s,
    triangle_deg,
    triangle_period_s,
)
from .trajectory_record import Trajectory

FloatArray = npt.NDArray[np.float64]
Quantity = float | tuple[float, ...]
Fields = Mapping[str, Quantity | None]


class LimitReport(Protocol):
    """What a kind's `check_limits` reports to (`stream_check.LimitCheck`), each call naming the protocol
    FIELD that sets the value; `problems` holds (field, message) of every limit broken so far."""

    def range(self, field: str, lo: float, hi: float, what: str = "") -> None: ...
    def rate(self, field: str, value: float, what: str) -> None: ...
    def accel(self, field: str, value: float, what: str) -> None: ...
    def samples(self, field: str) -> None: ...
    @property
    def problems(self) -> list[tuple[str, str]]: ...


BINDING_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_\-]*\.[A-Za-z][A-Za-z0-9_]*$")
"""A binding: `<factor>.<quantity>` (a factor name as the protocol declares it, a quantity key)."""


def is_binding(value: object) -> bool:
    return isinstance(value, str) and BINDING_PATTERN.match(value) is not None


def _binding_or(kind: str, check: Callable[[object], object]) -> Callable[[object], object]:
    def validate(value: object) -> object:
        if isinstance(value, str):
            if not is_binding(value):
                raise ValueError(
                    f"expected {kind} or a binding `<factor>.<quantity>` (e.g. speed.speed_deg_s), "
                    f"got {value!r}"
                )
            return value
        return check(value)

    return validate


def _number(positive: bool) -> Callable[[object], object]:
    def check(value: object) -> object:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"expected a number, got {value!r}")
        number = float(value)
        if not math.isfinite(number):
            raise ValueError(f"expected a finite number, got {value!r}")
        if positive and number <= 0:
            raise ValueError(f"must be greater than 0, got {number:g}")
        return number

    return check


def _range(value: object) -> object:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ValueError(f"expected a range [low, high], got {value!r}")
    lo, hi = (_number(False)(v) for v in value)
    assert isinstance(lo, float) and isinstance(hi, float)
    if not lo < hi:
        raise ValueError(f"range must be [low, high] with low < high, got [{lo:g}, {hi:g}]")
    return (lo, hi)


RangePair = tuple[float, float]
BindableFloat = Annotated[float | str, BeforeValidator(_binding_or("a number", _number(False)))]
"""A number, or a binding `<factor>.<quantity>`."""
BindablePositive = Annotated[float | str, BeforeValidator(_binding_or("a positive number", _number(True)))]
"""A positive number, or a binding."""
BindableRange = Annotated[RangePair | str, BeforeValidator(_binding_or("a range [low, high]", _range))]
"""A range [low, high] (low < high), or a binding."""


@dataclass(frozen=True)
class BuildContext:
    """What a kind's `build` may need besides its fields: the trajectory's name (for messages), the folder
    a file is read from, the joint (a file's angle column) and the joint's limits."""

    name: str
    base_dir: Path
    joint: str | None = None
    limits: SafetyLimits | None = None

    @property
    def where(self) -> str:
        return f"trajectory {self.name!r}"


class TrajectoryKindSpec(BaseModel):
    """A trajectory kind: its model's fields are the protocol's keys (`kind` a literal naming the kind); the
    class declares the rest."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    kind: str
    description: str = ""

    #: the fields that may be bound to a factor quantity (the binding's quantity must carry the field's
    #: unit suffix: `speed_deg_s` binds to a `..._deg_s` quantity)
    bindable: ClassVar[tuple[str, ...]] = ()
    #: the field that sets how long it lasts: named when the trajectory is too long to sample
    length_field: ClassVar[str] = "duration_s"

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        """The plan's `Trajectory` (`build_trajectory` names it), the bindable fields taking the values
        `fields` (a bound field's factor quantity, or the constant written). `InvalidInput` names the
        trajectory and the field."""
        raise NotImplementedError(f"trajectory kind {self.kind!r} has no build")

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        """The joint angles at `time_s` (the output ticks, `sampling.sample_trajectory`)."""
        raise NotImplementedError(f"trajectory kind {trajectory.profile!r} has no sample")

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        """Report to `check` what the joint's limits must allow, field by field (a closed form where the
        kind has one, else `check.samples`)."""
        check.samples(trajectory.profile)

    @staticmethod
    def describe(trajectory: Trajectory) -> str:
        """The trajectory in a line of `--plan`."""
        return f"{trajectory.profile} {trajectory.source or ''}".strip()


class SinusoidSpec(TrajectoryKindSpec):
    """Eq 24: angle = mean + amplitude * sin(2*pi*t/p), mean and amplitude from `range_deg`; its peak
    speed is amplitude * 2*pi/p (Eq 25) = `speed_deg_s`, so p = 2*pi*amplitude / speed_deg_s.
    Starts at the mean, moving up; lasts `periods` periods."""

    kind: Literal["sinusoid"]
    range_deg: BindableRange
    speed_deg_s: BindablePositive
    periods: float = Field(gt=0)

    bindable: ClassVar[tuple[str, ...]] = ("range_deg", "speed_deg_s")
    length_field: ClassVar[str] = "periods"

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        lo, hi = _pair(fields["range_deg"])
        speed = _num(fields["speed_deg_s"])
        amplitude = (hi - lo) / 2.0
        period = sinusoid_period_s(amplitude, speed)  # Eq 25
        return Trajectory(
            profile="sinusoid",
            mean_deg=(hi + lo) / 2.0,
            amplitude_deg=amplitude,
            period_s=period,
            params=(("range_deg", (lo, hi)), ("speed_deg_s", speed), ("periods", self.periods)),
            duration_s=self.periods * period,
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        return sinusoid_deg(time_s, *_sine(trajectory))

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        mean, a, period = _sine(trajectory)
        speed = 2.0 * math.pi * a / period  # Eq 25
        check.range("range_deg", mean - a, mean + a)
        check.rate("speed_deg_s", speed, "its peak speed (Eq 25)")
        check.accel(
            "speed_deg_s", sinusoid_peak_accel_deg_s2(a, speed), "its peak acceleration speed²/amplitude"
        )

    @staticmethod
    def describe(trajectory: Trajectory) -> str:
        mean, amplitude, period = _sine(trajectory)
        return f"{mean:g}+{amplitude:g}*sin(2*pi*t/{period:.2f})"


class TriangleSpec(TrajectoryKindSpec):
    """Constant speed `speed_deg_s` between the ends of `range_deg`, turned round at the ends at the
    constant acceleration `corner_accel_deg_s2` (default: the joint's acceleration limit). Starts and ends
    at rest at the low end; a cycle is low -> high -> low, `cycles` may be a whole or a half number."""

    kind: Literal["triangle"]
    range_deg: BindableRange
    speed_deg_s: BindablePositive
    cycles: float = Field(gt=0)
    corner_accel_deg_s2: BindablePositive | None = None

    @field_validator("cycles")
    @classmethod
    def _half_cycles(cls, value: float) -> float:
        if abs(2.0 * value - round(2.0 * value)) > 1e-9:
            raise ValueError(f"must be a whole or half number of cycles (low -> high -> low), got {value:g}")
        return value

    bindable: ClassVar[tuple[str, ...]] = ("range_deg", "speed_deg_s", "corner_accel_deg_s2")
    length_field: ClassVar[str] = "cycles"

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        """Without `corner_accel_deg_s2` it turns at the joint's acceleration limit."""
        lo, hi = _pair(fields["range_deg"])
        speed = _num(fields["speed_deg_s"])
        given = fields.get("corner_accel_deg_s2")
        if given is not None:
            accel = _num(given)
        elif at.limits is not None:
            accel = at.limits.max_accel_deg_s2
        else:
            raise InvalidInput(
                f"{at.where}: corner_accel_deg_s2 is not given and no joint acceleration limit is known"
            )
        if hi - lo < speed * speed / accel:
            raise InvalidInput(
                f"{at.where}: speed_deg_s {speed:g} deg/s cannot be reached within range_deg [{lo:g}, {hi:g}] "
                f"with corners at {accel:g} deg/s² (it needs a range of at least speed²/accel = "
                f"{speed * speed / accel:.4g} deg)"
            )
        return Trajectory(
            profile="triangle",
            params=(
                ("range_deg", (lo, hi)),
                ("speed_deg_s", speed),
                ("cycles", self.cycles),
                ("corner_accel_deg_s2", accel),
            ),
            duration_s=self.cycles * triangle_period_s(hi - lo, speed, accel),
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        lo, hi = _pair(trajectory.param("range_deg"))
        num = trajectory.number
        return triangle_deg(time_s, lo, hi, num("speed_deg_s"), num("corner_accel_deg_s2"))

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        lo, hi = _pair(trajectory.param("range_deg"))
        check.range("range_deg", lo, hi)
        check.rate("speed_deg_s", trajectory.number("speed_deg_s"), "its constant speed")
        check.accel(
            "corner_accel_deg_s2", trajectory.number("corner_accel_deg_s2"), "its corners' acceleration"
        )


class FileSpec(TrajectoryKindSpec):
    """An angle-vs-time file, relative to the protocol's folder: a CSV whose comment lines (`#`) state
    where the motion comes from, then a column row with `time_s` and one angle column per joint (named
    by the joint, or `angle_deg` for a single joint), then numbers; or a MATLAB .mat with those variables.
    `origin` states the source when the file's comments do not."""

    kind: Literal["file"]
    file: str = Field(min_length=1)
    origin: str = ""

    length_field: ClassVar[str] = "file"

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        """The file read from `at.base_dir`: the joint's angle column, else `angle_deg`."""
        try:
            data = load_trajectory_file(confined_path(at.base_dir, self.file), at.joint)
        except OutsideFolder as exc:
            raise InvalidInput(f"{at.where}: file: {exc}") from None
        except InvalidInput as exc:
            raise InvalidInput(f"{at.where}: {exc.message}") from None
        origin = self.origin or (data.header.splitlines()[0] if data.header else "")
        if not origin:
            raise InvalidInput(
                f"{at.where}: file {self.file}: state where the motion comes from, in comment lines (#) "
                "before the column row or as `origin:` in the protocol"
            )
        return Trajectory(
            profile="file",
            source=self.file,
            params=(("column", data.column), ("origin", origin)),
            duration_s=data.duration_s,
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        assert trajectory.source is not None
        column = dict(trajectory.params).get("column")  # the angle column `build` chose
        return load_trajectory_file(
            base_dir / trajectory.source, column if isinstance(column, str) else None
        ).at(time_s)


class IdentificationSpec(TrajectoryKindSpec):
    """The Eq 4-7 identification motion (Figure 25) between the ends of `range_deg`, repeated every
    `repetition_s` (odd repeats backwards: no jump), its carrier period going from `initial_period_s` to
    `final_period_s` (Eq 5); lasts `total_s`. See `trajectories.identification_deg`."""

    kind: Literal["identification"]
    range_deg: BindableRange
    total_s: float = Field(gt=0)
    repetition_s: float = Field(gt=0)
    initial_period_s: float = Field(gt=0)
    final_period_s: float = Field(gt=0)

    bindable: ClassVar[tuple[str, ...]] = ("range_deg",)

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        lo, hi = _pair(fields["range_deg"])
        periods = ("repetition_s", "initial_period_s", "final_period_s")
        return Trajectory(
            profile="identification",
            params=(("min_deg", lo), ("max_deg", hi), *((f, getattr(self, f)) for f in periods)),
            duration_s=self.total_s,
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        return identification_deg(time_s, *(trajectory.number(f) for f, _ in trajectory.params))

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        """Its range; then, no closed form: its samples at the output rate (the last, fastest period)."""
        check.range("range_deg", trajectory.number("min_deg"), trajectory.number("max_deg"))
        if not check.problems:
            check.samples("final_period_s")


Angle = TypeVar("Angle")


class RampedStepFields(BaseModel, Generic[Angle]):
    """A ramped step's fields: hold `from_deg` for `settle_s`, move by `step_deg` over `ramp_s` (raised
    cosine: peak speed pi/2 * step/ramp, peak acceleration pi^2/2 * step/ramp^2), hold for `hold_s`. The
    angles are numbers (the calibration step, schema.CalibrationStepSpec) or bindable (a trajectory)."""

    from_deg: Angle
    step_deg: Angle
    ramp_s: float = Field(ge=0)
    hold_s: float = Field(gt=0)
    settle_s: float = Field(gt=0)


class RampedStepSpec(RampedStepFields[BindableFloat], TrajectoryKindSpec):
    """A ramped step (RampedStepFields) as a trajectory. `ramp_s = 0` would be a true step: the plan-time
    check refuses it (over any rate limit)."""

    kind: Literal["ramped_step"]

    bindable: ClassVar[tuple[str, ...]] = ("from_deg", "step_deg")

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        return Trajectory(
            profile="ramped_step",
            params=(
                ("from_deg", _num(fields["from_deg"])),
                ("step_deg", _num(fields["step_deg"])),
                ("settle_s", self.settle_s),
                ("ramp_s", self.ramp_s),
                ("hold_s", self.hold_s),
            ),
            duration_s=self.settle_s + self.ramp_s + self.hold_s,
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        num = trajectory.number
        return calibration_step_deg(time_s, num("from_deg"), num("step_deg"), num("settle_s"), num("ramp_s"))

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        start, step, ramp = (trajectory.number(f) for f in ("from_deg", "step_deg", "ramp_s"))
        check.range("from_deg", start, start)
        check.range(
            "step_deg", start + step, start + step, f"the step's end from_deg + step_deg = {start + step:g}"
        )
        check.rate(
            "ramp_s", calibration_step_peak_speed_deg_s(step, ramp), "the ramp's peak speed pi/2*step/ramp"
        )
        check.accel(
            "ramp_s",
            calibration_step_peak_accel_deg_s2(step, ramp),
            "the ramp's peak acceleration pi²/2*step/ramp²",
        )


class HoldSpec(TrajectoryKindSpec):
    """`angle_deg` held for `duration_s`."""

    kind: Literal["hold"]
    angle_deg: BindableFloat
    duration_s: float = Field(gt=0)

    bindable: ClassVar[tuple[str, ...]] = ("angle_deg",)

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        params = (("angle_deg", _num(fields["angle_deg"])),)
        return Trajectory(profile="hold", params=params, duration_s=self.duration_s)

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        return hold_deg(time_s, trajectory.number("angle_deg"))

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitReport) -> None:
        angle = trajectory.number("angle_deg")
        check.range("angle_deg", angle, angle)


TRAJECTORY_KINDS: dict[str, type[TrajectoryKindSpec]] = {
    "sinusoid": SinusoidSpec,
    "triangle": TriangleSpec,
    "file": FileSpec,
    "identification": IdentificationSpec,
    "ramped_step": RampedStepSpec,
    "hold": HoldSpec,
}
"""The registry of trajectory kinds: kind -> its model. `register_trajectory_kind` adds one."""


class _RegisteredKinds:
    """A trajectory's pydantic schema: the registered kinds told apart by `kind` (and `per_joint` for a
    protocol's trajectories), built when a model that holds trajectories is built, or rebuilt."""

    def __init__(self, *, per_joint: bool) -> None:
        self.per_joint = per_joint

    def __get_pydantic_core_schema__(self, source: Any, handler: GetCoreSchemaHandler) -> CoreSchema:
        kinds: dict[str, type[TrajectoryKindSpec]] = dict(TRAJECTORY_KINDS)
        if self.per_joint:
            kinds["per_joint"] = PerJointSpec
        choices: dict[str | int, CoreSchema] = {k: handler.generate_schema(m) for k, m in kinds.items()}
        return core_schema.tagged_union_schema(choices, discriminator="kind")


JointTrajectorySpec = Annotated[TrajectoryKindSpec, _RegisteredKinds(per_joint=False)]
"""The motion of one joint: one of the registered kinds."""


class PerJointSpec(TrajectoryKindSpec):
    """A multi-joint protocol's motion given joint by joint: `joints: {<joint>: <a trajectory of any
    other kind>}`, one entry per driven joint. The joints share the trial's time: every entry must last
    the same number of output ticks."""

    kind: Literal["per_joint"]
    joints: Annotated[dict[str, JointTrajectorySpec], Field(min_length=1)]


TrajectorySpec = Annotated[TrajectoryKindSpec, _RegisteredKinds(per_joint=True)]
"""A protocol's trajectory: one of the registered kinds, or `per_joint`."""

_HOLDING_TRAJECTORIES: list[type[BaseModel]] = [PerJointSpec]
"""The models whose schema holds trajectories (`holds_trajectories`), in build order."""


def holds_trajectories(model: type[BaseModel]) -> None:
    """Declare that `model`'s schema holds trajectories: it is rebuilt when the registry changes."""
    _HOLDING_TRAJECTORIES.append(model)


def register_trajectory_kind(spec: type[TrajectoryKindSpec]) -> None:
    """Add a trajectory kind: protocols may use it from now on (a kind already registered is refused)."""
    (name,) = get_args(spec.model_fields["kind"].annotation)
    if name in TRAJECTORY_KINDS or name == "per_joint":
        raise ValueError(f"trajectory kind {name!r} is already registered")
    TRAJECTORY_KINDS[str(name)] = spec
    _rebuild()


def deregister_trajectory_kind(name: str) -> None:
    """Remove a kind added by `register_trajectory_kind`."""
    del TRAJECTORY_KINDS[name]
    _rebuild()


def _rebuild() -> None:
    for model in _HOLDING_TRAJECTORIES:
        model.model_rebuild(force=True)


def trajectory_kind(profile: str) -> type[TrajectoryKindSpec]:
    """The registered kind of a plan trajectory's `profile` (`ValueError` for an unknown one)."""
    found = TRAJECTORY_KINDS.get(profile)
    if found is None:
        raise ValueError(f"unknown trajectory profile {profile!r}")
    return found


def kind_names() -> tuple[str, ...]:
    """Every `kind` a protocol's trajectory may have: the registered kinds and `per_joint`."""
    return (*TRAJECTORY_KINDS, "per_joint")


def joint_spec(spec: TrajectorySpec, joint: str) -> tuple[TrajectorySpec, tuple[str, ...]]:
    """The motion of `joint` under `spec` and the YAML location suffix of its fields: a `per_joint`
    entry (`joints.<joint>`), else `spec` itself (a single joint, or a file with one column per joint)."""
    if isinstance(spec, PerJointSpec):
        return spec.joints[joint], ("joints", joint)
    return spec, ()


def trajectory_files(spec: TrajectorySpec) -> list[str]:
    """The files a trajectory reads, as written: a file's, or those of a `per_joint` trajectory's entries."""
    if isinstance(spec, PerJointSpec):
        return [f for entry in spec.joints.values() for f in trajectory_files(entry)]
    return [spec.file] if isinstance(spec, FileSpec) else []


def trajectory_bindings(spec: TrajectorySpec) -> dict[str, str]:
    """field -> "<factor>.<quantity>" for every field of `spec` bound to a factor quantity (a `per_joint`
    spec: `joints.<joint>.<field>` for its entries)."""
    out: dict[str, str] = {}
    if isinstance(spec, PerJointSpec):
        for joint, entry in spec.joints.items():
            out.update({f"joints.{joint}.{k}": v for k, v in trajectory_bindings(entry).items()})
        return out
    for field in type(spec).bindable:
        value = getattr(spec, field)
        if isinstance(value, str):
            out[field] = value
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
    """The trajectory `name` commands: `spec`'s kind builds it, each bound field taking its value from
    `values` (field -> the resolved factor quantity, checked here). A file is read from `base_dir` (its
    angle column: `joint`'s, else `angle_deg`); a triangle without `corner_accel_deg_s2` turns at
    `limits.max_accel_deg_s2`. `InvalidInput` names the trajectory and the field."""
    fields: dict[str, Quantity | None] = {}
    for field in type(spec).bindable:
        written = getattr(spec, field)
        fields[field] = written if not isinstance(written, str) else _bound(name, field, written, values)
    built = spec.build(fields, BuildContext(name, base_dir, joint, limits))
    return dataclasses.replace(built, name=name)


def _bound(name: str, field: str, binding: str, values: Mapping[str, Quantity]) -> Quantity:
    """The resolved value of a bound field, checked as the field checks a constant."""
    if field not in values:
        raise InvalidInput(
            f"trajectory {name!r}: {field} is bound to {binding} but no value was given for it"
        )
    check = _range if field == "range_deg" else _number(field in ("speed_deg_s", "corner_accel_deg_s2"))
    try:
        return check(values[field])  # type: ignore[return-value]
    except ValueError as exc:
        raise InvalidInput(f"trajectory {name!r}: {field} (bound to {binding}): {exc}") from None


def _sine(trajectory: Trajectory) -> tuple[float, float, float]:
    """A sinusoid's mean, amplitude and period."""
    mean, amplitude, period = trajectory.mean_deg, trajectory.amplitude_deg, trajectory.period_s
    assert mean is not None and amplitude is not None and period
    return mean, amplitude, period


def _pair(value: object) -> tuple[float, float]:
    assert isinstance(value, tuple) and len(value) == 2
    return float(value[0]), float(value[1])


def _num(value: object) -> float:
    assert isinstance(value, float | int)
    return float(value)
