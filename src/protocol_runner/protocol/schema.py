"""The protocol file's schema (schema_version 2): pydantic models, immutable, unknown keys rejected.

Nothing here names a campaign: factors, their levels and quantities, the device's elements and the
trajectories are whatever the file declares (docs/protocol.md is the reference). Cross-field checks
(levels that exist, bindings whose units match, ranges inside the joint's range, unique keys, ...) live in
`protocol/validate.py` and `protocol/resolve.py` so that each error can name the exact field and line.

The parts live by idea: schema_base (strict model, shared field types), schema_device (factors, device),
schema_matrix (sets and configurations), schema_rig (resolved rig), schema_report (report section), and
trajectory_specs (trajectory kinds); this module holds the calibration check, processing, fits and the
whole `Protocol`, and re-exports the parts' public names.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Discriminator, Field, PrivateAttr, Tag, field_validator, model_validator

from protocol_runner.protocol.expectations import ExpectationSpec
from protocol_runner.protocol.schema_base import (  # noqa: F401  (re-exported)
    Identifier,
    LevelName,
    RangePair,
    _check_range,
    _Model,
)
from protocol_runner.protocol.schema_device import (  # noqa: F401  (re-exported)
    RESERVED_LEVEL_KEYS,
    DeviceSpec,
    ElementSpec,
    Factor,
    JointDeviceSpec,
    LevelSpec,
    Quantity,
)
from protocol_runner.protocol.schema_matrix import (  # noqa: F401  (re-exported)
    RESERVED_CONFIGURATION_KEYS,
    ConfigurationSpec,
    FullFactorialSpec,
    LevelChoice,
    LevelList,
    OneFactorAtATimeSpec,
    SetSpec,
    TrajectoryByLevel,
    _GeneratorSpec,
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
from protocol_runner.protocol.trajectory_specs import RampedStepFields, TrajectorySpec, holds_trajectories

# ------------------------------------------------------------------------------------ trajectories


class CalibrationStepSpec(RampedStepFields[float], _Model):
    """The calibration check's move (a ramped step, thesis Appendix A "Calibration"), in numbers."""


class CalibrationCheckSpec(_Model):
    max_settle_error_deg: float = Field(gt=0)
    # the smallest calibration step whose response can carry a time constant: a step comparable to the
    # sensor noise and the servo's dead band gives a "time constant" of noise
    min_step_deg: float = Field(default=5.0, gt=0)
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
    # a fraction of the Nyquist frequency; below 1e-4 the zero-phase filter's initial conditions are a
    # singular system (and the filter passes nothing but the record's mean anyway)
    cutoff: float = Field(default=0.1, ge=1e-4, lt=1)
    ripple_db: float = Field(default=0.5, gt=0, le=40)


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


def _calibration_form(value: object) -> str:
    """One step for every joint, or a mapping joint -> step (every value a mapping): the form decides which
    is checked, so a wrong value of one step is one message at its field, not the other form's too."""
    if isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
        return "<per joint>"
    return "<one step>"


CalibrationStep = Annotated[
    Annotated[CalibrationStepSpec, Tag("<one step>")]
    | Annotated[dict[Identifier, CalibrationStepSpec], Tag("<per joint>")],
    Discriminator(_calibration_form),
]


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
    calibration_step: CalibrationStep
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


holds_trajectories(Protocol)  # rebuilt when a trajectory kind is registered
