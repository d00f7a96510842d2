"""The protocol's trajectory kinds as pydantic models (`trajectories:` of a schema_version 2 protocol).

One model per kind, told apart by `kind` (a discriminated union, unknown kinds and keys refused):

- `sinusoid`: Eq 24 from a range and a peak speed; the period follows from Eq 25 (p = 2*pi*A / v_peak).
- `triangle`: constant speed between the range's ends, turned round at a limited acceleration.
- `file`: an angle-vs-time CSV (or .mat) recorded elsewhere, its origin stated.
- `identification`: the Eq 4-7 motion (exponential envelope times cos^2, changing period), as rebuilt in
  `trajectories.identification_deg`.
- `ramped_step`: hold, a raised-cosine move by `step_deg`, hold (the calibration step of Appendix A).
- `hold`: one angle held.

A field typed `float | str` (or `RangePair | str`) may be BOUND to a factor quantity: a string
`"<factor>.<quantity>"` takes the value of that quantity in each configuration's level (issue 11, spec A).
`trajectory_bindings` lists them; `plan_trajectory.build_trajectory` takes their resolved values. Every other
field is a constant. Numbers are finite (no .inf / .nan); times and speeds are positive.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Annotated, Generic, Literal, TypeVar

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator

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


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    description: str = ""


class SinusoidSpec(_Spec):
    """Eq 24: angle = mean + amplitude * sin(2*pi*t/p), mean and amplitude from `range_deg`; its peak
    speed is amplitude * 2*pi/p (Eq 25) = `speed_deg_s`, so p = 2*pi*amplitude / speed_deg_s.
    Starts at the mean, moving up; lasts `periods` periods."""

    kind: Literal["sinusoid"]
    range_deg: BindableRange
    speed_deg_s: BindablePositive
    periods: float = Field(gt=0)


class TriangleSpec(_Spec):
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


class FileSpec(_Spec):
    """An angle-vs-time file, relative to the protocol's folder: a CSV whose comment lines (`#`) state
    where the motion comes from, then a column row with `time_s` and one angle column per joint (named
    by the joint, or `angle_deg` for a single joint), then numbers; or a MATLAB .mat with those variables.
    `origin` states the source when the file's comments do not."""

    kind: Literal["file"]
    file: str = Field(min_length=1)
    origin: str = ""


class IdentificationSpec(_Spec):
    """The Eq 4-7 identification motion (Figure 25) between the ends of `range_deg`, repeated every
    `repetition_s` (odd repeats backwards: no jump), its carrier period going from `initial_period_s` to
    `final_period_s` (Eq 5); lasts `total_s`. See `trajectories.identification_deg`."""

    kind: Literal["identification"]
    range_deg: BindableRange
    total_s: float = Field(gt=0)
    repetition_s: float = Field(gt=0)
    initial_period_s: float = Field(gt=0)
    final_period_s: float = Field(gt=0)


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


class RampedStepSpec(RampedStepFields[BindableFloat], _Spec):
    """A ramped step (RampedStepFields) as a trajectory. `ramp_s = 0` would be a true step: the plan-time
    check refuses it (over any rate limit)."""

    kind: Literal["ramped_step"]


class HoldSpec(_Spec):
    """`angle_deg` held for `duration_s`."""

    kind: Literal["hold"]
    angle_deg: BindableFloat
    duration_s: float = Field(gt=0)


JointTrajectorySpec = Annotated[
    SinusoidSpec | TriangleSpec | FileSpec | IdentificationSpec | RampedStepSpec | HoldSpec,
    Field(discriminator="kind"),
]
"""The motion of one joint."""


class PerJointSpec(_Spec):
    """A multi-joint protocol's motion given joint by joint: `joints: {<joint>: <a trajectory of any
    other kind>}`, one entry per driven joint. The joints share the trial's time: every entry must last
    the same number of output ticks."""

    kind: Literal["per_joint"]
    joints: Annotated[dict[str, JointTrajectorySpec], Field(min_length=1)]


TrajectorySpec = Annotated[
    SinusoidSpec | TriangleSpec | FileSpec | IdentificationSpec | RampedStepSpec | HoldSpec | PerJointSpec,
    Field(discriminator="kind"),
]
TRAJECTORY_KINDS: tuple[str, ...] = (
    "sinusoid",
    "triangle",
    "file",
    "identification",
    "ramped_step",
    "hold",
    "per_joint",
)

BINDABLE_FIELDS: dict[str, tuple[str, ...]] = {
    "sinusoid": ("range_deg", "speed_deg_s"),
    "triangle": ("range_deg", "speed_deg_s", "corner_accel_deg_s2"),
    "file": (),
    "identification": ("range_deg",),
    "ramped_step": ("from_deg", "step_deg"),
    "hold": ("angle_deg",),
    "per_joint": (),
}
"""The fields of each kind that may be bound to a factor quantity (the binding's quantity must carry the
field's unit suffix: `speed_deg_s` binds to a `..._deg_s` quantity)."""


def joint_spec(spec: TrajectorySpec, joint: str) -> tuple[TrajectorySpec, tuple[str, ...]]:
    """The motion of `joint` under `spec` and the YAML location suffix of its fields: a `per_joint`
    entry (`joints.<joint>`), else `spec` itself (a single joint, or a file with one column per joint)."""
    if isinstance(spec, PerJointSpec):
        return spec.joints[joint], ("joints", joint)
    return spec, ()


def trajectory_bindings(spec: TrajectorySpec) -> dict[str, str]:
    """field -> "<factor>.<quantity>" for every field of `spec` bound to a factor quantity (a `per_joint`
    spec: `joints.<joint>.<field>` for its entries)."""
    out: dict[str, str] = {}
    if isinstance(spec, PerJointSpec):
        for joint, entry in spec.joints.items():
            out.update({f"joints.{joint}.{k}": v for k, v in trajectory_bindings(entry).items()})
        return out
    for field in BINDABLE_FIELDS[spec.kind]:
        value = getattr(spec, field)
        if isinstance(value, str):
            out[field] = value
    return out
