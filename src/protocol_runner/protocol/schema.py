"""The protocol file's schema (schema_version 2): pydantic models, immutable, unknown keys rejected.

Nothing here names a campaign: factors, their levels and quantities, the device's elements and the
trajectories are whatever the file declares (docs/protocol.md is the reference). Cross-field checks
(levels that exist, bindings whose units match, ranges inside the joint's range, unique keys, ...) live in
`protocol/validate.py` and `protocol/resolve.py` so that each error can name the exact field and line.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import (
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    StrictInt,
    field_validator,
    model_validator,
)

from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.protocol.schema_base import (
    Identifier,
    LevelName,
    RangePair,
    _check_range,
    _int_to_str,
    _Model,
)
from protocol_runner.protocol.schema_report import (  # noqa: F401  (re-exported)
    CitationsSpec,
    ComparisonSpec,
    PredictionSpec,
    ReportSpec,
)
from protocol_runner.protocol.schema_rig import (  # noqa: F401  (re-exported)
    BoltTorque,
    CalibrationTablesSpec,
    InputSpec,
    JointOverride,
    JointSpec,
    OutputSpec,
    RigOverrides,
    RigSpec,
    SafetyOverride,
    SafetySpec,
)
from protocol_runner.protocol.trajectory_specs import TrajectorySpec
from protocol_runner.protocol.units import compound_unit_problem, known_suffixes, unit_suffix

# ----------------------------------------------------------------------------------------- factors

RESERVED_LEVEL_KEYS = ("same_as", "description", "setup")
Quantity = float | tuple[float, ...]


def _quantity_value(name: str, value: object) -> Quantity:
    if isinstance(value, bool) or not isinstance(value, int | float | list | tuple):
        raise ValueError(f"quantity {name!r} must be a number or a list of numbers, got {value!r}")
    if isinstance(value, list | tuple):
        items = [_quantity_value(name, v) for v in value]
        if not items or any(isinstance(v, tuple) for v in items):
            raise ValueError(f"quantity {name!r} must be a number or a flat list of numbers, got {value!r}")
        if name.endswith("range_deg") and not (len(items) == 2 and items[0] < items[1]):  # type: ignore[operator]
            raise ValueError(f"{name} must be [low, high] with low < high, got {value!r}")
        return tuple(float(v) for v in items)  # type: ignore[arg-type]
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"quantity {name!r} must be finite, got {value!r}")
    return number


class LevelSpec(_Model):
    """One level of a factor: quantities (keys ending with a unit suffix, protocol/units.py), or
    `same_as` another level of the same factor; `description` and `setup` (operator checklist text)."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    same_as: LevelName | None = None
    description: str = ""
    setup: str = ""

    @model_validator(mode="before")
    @classmethod
    def _quantities(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        out = dict(data)
        for key, value in data.items():
            if key in RESERVED_LEVEL_KEYS:
                continue
            if unit_suffix(str(key)) is None:
                raise ValueError(
                    f"{key!r}: a quantity's name must end with a unit suffix ({known_suffixes()}); "
                    f"reserved keys: {', '.join(RESERVED_LEVEL_KEYS)}"
                )
            compound = compound_unit_problem(str(key))
            if compound is not None:
                raise ValueError(compound)
            out[key] = _quantity_value(str(key), value)
        return out

    @property
    def quantities(self) -> tuple[tuple[str, Quantity], ...]:
        return tuple((k, v) for k, v in (self.model_extra or {}).items())


def _str_keys(value: object) -> object:
    if isinstance(value, dict):
        return {_int_to_str(k): v for k, v in value.items()}
    return value


Factor = Annotated[dict[str, LevelSpec], BeforeValidator(_str_keys), Field(min_length=1)]

# ------------------------------------------------------------------------------------------- device


class ElementSpec(_Model):
    """One element of the device: `name`, `type` (models/elements.py ELEMENT_TYPES) and its parameters,
    each a constant or a binding "<factor>.<quantity>" (checked in protocol/resolve.py)."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    name: Identifier
    type: str

    @property
    def params(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class JointDeviceSpec(_Model):
    """The elements one driven joint carries (a multi-joint protocol's `device.joints.<joint>`)."""

    description: str = ""
    elements: list[ElementSpec] = Field(min_length=1)


class DeviceSpec(_Model):
    """The device under test: `elements` (one driven joint), or `joints: {<joint>: {elements: [...]}}`
    (a multi-joint protocol: each driven joint its own elements; a joint may carry none)."""

    name: str = ""
    description: str = ""
    elements: list[ElementSpec] = Field(default_factory=list)
    joints: dict[Identifier, JointDeviceSpec] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _one_form(self) -> Any:
        if bool(self.elements) == bool(self.joints):
            raise ValueError("give exactly one of `elements` (one joint) and `joints` (elements per joint)")
        return self

    def located_elements(self) -> list[tuple[str, tuple[str | int, ...], ElementSpec]]:
        """(joint or "", YAML location, element) for every element, in file order."""
        if self.elements:
            return [("", ("device", "elements", i), el) for i, el in enumerate(self.elements)]
        return [
            (joint, ("device", "joints", joint, "elements", i), el)
            for joint, spec in self.joints.items()
            for i, el in enumerate(spec.elements)
        ]


# ------------------------------------------------------------------------------------ trajectories


class CalibrationStepSpec(_Model):
    """The calibration check's move (a ramped step, thesis Appendix A "Calibration")."""

    from_deg: float
    step_deg: float
    ramp_s: float = Field(ge=0)
    hold_s: float = Field(gt=0)
    settle_s: float = Field(gt=0)


class CalibrationCheckSpec(_Model):
    max_settle_error_deg: float = Field(gt=0)
    time_constant_s: RangePair
    max_drift_deg: float = Field(gt=0)
    max_time_constant_change_s: float = Field(gt=0)

    _range = field_validator("time_constant_s")(_check_range)


# ---------------------------------------------------------------------------------- processing, fits


class TransitionSpec(_Model):
    tolerance_deg: float = Field(gt=0)
    points: int = Field(ge=1)


class FilterSpec(_Model):
    kind: Literal["butterworth", "chebyshev"]
    order: int = Field(default=10, ge=1, le=20)
    cutoff: float = Field(default=0.1, gt=0, lt=1)
    ripple_db: float = Field(default=0.5, gt=0)


class ScalingSpec(_Model):
    tolerance_deg: float = Field(gt=0)
    max_iterations: int = Field(ge=1, le=20)


class ProcessingSpec(_Model):
    transition: TransitionSpec
    filter: FilterSpec
    brace_off_scaling: ScalingSpec
    subtraction: Literal["equal_angle", "equal_time"] = "equal_angle"
    centre_for_fit: bool = True


class SpringFitSpec(_Model):
    enabled: bool = True


class BoucWenFitSpec(_Model):
    enabled: bool = True
    starts: int = Field(default=8, ge=1, le=200)
    cross_validate: bool = True
    # torque = backbone(angle) + z: "polynomial" (a polynomial of the angle through the loops' midline),
    # "elements" (the device's elastic elements with the element fit's parameters, refitted on the trials
    # each fit uses; g = 0 when the device has none) or "none" (the thesis form, torque = z)
    backbone: Literal["polynomial", "elements", "none"] = "polynomial"
    backbone_degree: int = Field(default=9, ge=0, le=15)

    @property
    def polynomial_degree(self) -> int | None:
        """The backbone polynomial's degree, or None for the thesis form torque = z."""
        return self.backbone_degree if self.backbone == "polynomial" else None


class FitsSpec(_Model):
    spring: SpringFitSpec = SpringFitSpec()
    bouc_wen: BoucWenFitSpec = BoucWenFitSpec()


# ------------------------------------------------------------------------------------- the matrix

RESERVED_CONFIGURATION_KEYS = ("key", "run", "trajectory", "trials", "description")


def _levels_as_str(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: (v if k in RESERVED_CONFIGURATION_KEYS else _int_to_str(v)) for k, v in data.items()}
    return data


class ConfigurationSpec(_Model):
    """An explicit row: reserved keys, and `<factor>: <level label>` for the factors it sets."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    key: StrictInt = Field(ge=1)
    run: StrictInt = Field(ge=1)
    trajectory: Identifier
    trials: StrictInt = Field(ge=1, le=50)
    description: str = ""

    @model_validator(mode="before")
    @classmethod
    def _labels(cls, data: Any) -> Any:
        data = _levels_as_str(data)
        if isinstance(data, dict):
            for k, v in data.items():
                if k not in RESERVED_CONFIGURATION_KEYS and not isinstance(v, str):
                    raise ValueError(f"{k}: a factor's level label, got {v!r}")
        return data

    @property
    def levels(self) -> dict[str, str]:
        """factor -> level label, as written."""
        return {k: str(v) for k, v in (self.model_extra or {}).items()}


LevelList = Annotated[list[LevelName], Field(min_length=1)]
LevelChoice = LevelList | Literal["all"]


class TrajectoryByLevel(_Model):
    factor: Identifier
    levels: Annotated[dict[str, Identifier], BeforeValidator(_str_keys)]


class _GeneratorSpec(_Model):
    trajectory: Identifier | None = None
    trajectory_by_level: TrajectoryByLevel | None = None
    trials: StrictInt = Field(ge=1, le=50)
    description: str = ""

    @model_validator(mode="after")
    def _one_trajectory(self) -> Any:
        if (self.trajectory is None) == (self.trajectory_by_level is None):
            raise ValueError("give exactly one of `trajectory` and `trajectory_by_level`")
        return self


class FullFactorialSpec(_GeneratorSpec):
    """Every combination of the listed factors' levels (`all` = every declared level, in declaration
    order; the LAST factor varies fastest), each with the `fixed` levels."""

    factors: Annotated[dict[Identifier, LevelChoice], Field(min_length=1)]
    fixed: Annotated[dict[Identifier, LevelName], BeforeValidator(_str_keys)] = Field(default_factory=dict)


class OneFactorAtATimeSpec(_GeneratorSpec):
    """The baseline, then each factor of `vary` set to each of its listed levels in turn (the others at
    the baseline). A listed level equal to the baseline's is skipped (the baseline is already there)."""

    baseline: Annotated[dict[Identifier, LevelName], BeforeValidator(_str_keys)] = Field(min_length=1)
    vary: Annotated[dict[Identifier, LevelList], Field(min_length=1)]
    include_baseline: bool = True


class SetSpec(_Model):
    name: Identifier
    condition: str
    configurations: list[ConfigurationSpec] = Field(default_factory=list)
    full_factorial: FullFactorialSpec | None = None
    one_factor_at_a_time: OneFactorAtATimeSpec | None = None

    @model_validator(mode="after")
    def _something(self) -> Any:
        if not self.configurations and self.full_factorial is None and self.one_factor_at_a_time is None:
            raise ValueError("a set needs `configurations`, `full_factorial` or `one_factor_at_a_time`")
        return self


class Protocol(_Model):
    """A whole campaign (one protocol file). `rig` in the file names a rig file; after loading,
    `protocol.rig` is the resolved `RigSpec` of the driven joint."""

    schema_version: Literal[2]
    name: Identifier
    title: str = ""
    description: str = ""
    rig_name: str = Field(alias="rig", min_length=1)
    joint: Identifier | None = None
    joints: list[Identifier] | None = Field(default=None, min_length=1, max_length=12)
    rig_overrides: RigOverrides = RigOverrides()
    bolt_torques: list[BoltTorque] = Field(default_factory=list)
    factors: dict[Identifier, Factor] = Field(default_factory=dict)
    device: DeviceSpec | None = None
    trajectories: dict[Identifier, TrajectorySpec] = Field(min_length=1)
    calibration_step: CalibrationStepSpec | dict[Identifier, CalibrationStepSpec]
    calibration_check: CalibrationCheckSpec
    processing: ProcessingSpec
    fits: FitsSpec = FitsSpec()
    sets: list[SetSpec] = Field(min_length=1)
    report: ReportSpec = ReportSpec()
    expectations: list[ExpectationSpec] = Field(default_factory=list)

    _rigs: tuple[RigSpec, ...] = PrivateAttr(default=())

    @model_validator(mode="after")
    def _joint_or_joints(self) -> Any:
        if (self.joint is None) == (self.joints is None):
            raise ValueError("give exactly one of `joint` (one driven joint) and `joints` (several)")
        if self.joints is not None:
            seen = [j for i, j in enumerate(self.joints) if j in self.joints[:i]]
            if seen:
                raise ValueError(f"joints: {seen[0]!r} is listed twice")
        return self

    @property
    def multi_joint(self) -> bool:
        """True when the protocol names `joints:` (even one): trials drive a set of joints."""
        return self.joints is not None

    @property
    def rig(self) -> RigSpec:
        """The resolved rig of the driven joint (set by the loader); of a multi-joint protocol, the first
        driven joint's in channel order (`rigs` has every joint's)."""
        if not self._rigs:
            raise RuntimeError("the protocol's rig has not been resolved (load it with protocol.loader)")
        return self._rigs[0]

    @property
    def rigs(self) -> tuple[RigSpec, ...]:
        """Every driven joint's resolved rig, in output channel order."""
        if not self._rigs:
            raise RuntimeError("the protocol's rig has not been resolved (load it with protocol.loader)")
        return self._rigs

    @property
    def driven_joints(self) -> tuple[str, ...]:
        """The driven joints' names in channel order (resolved), or as written before resolution."""
        if self._rigs:
            return tuple(r.joint.name for r in self._rigs)
        return tuple(self.joints) if self.joints is not None else (str(self.joint),)

    def rig_of(self, joint: str) -> RigSpec:
        return next(r for r in self.rigs if r.joint.name == joint)

    def calibration_step_of(self, joint: str) -> CalibrationStepSpec:
        """The calibration step of a joint (the single `calibration_step`, or its entry per joint)."""
        step = self.calibration_step
        return step if isinstance(step, CalibrationStepSpec) else step[joint]

    def with_rig(self, rig: RigSpec) -> Protocol:
        return self.with_rigs((rig,))

    def with_rigs(self, rigs: tuple[RigSpec, ...]) -> Protocol:
        out = self.model_copy()
        out._rigs = tuple(rigs)
        return out

    def configurations(self) -> list[tuple[SetSpec, ConfigurationSpec]]:
        """Every configuration with its set, in execution order (generators expanded by the loader)."""
        return [(s, c) for s in self.sets for c in s.configurations]

    def profile_of(self, cfg: ConfigurationSpec) -> str:
        """The kind of a configuration's trajectory (sinusoid, file, ...)."""
        return self.trajectories[cfg.trajectory].kind
