"""The protocol file's schema: pydantic models, immutable, unknown keys rejected.

The shapes mirror `protocols/knee_phase1.yaml` (thesis Appendix A). Nothing here assumes a knee: the
joint, its channels, ranges and calibration come from the file. Cross-field checks (levels that exist,
ranges inside the joint's range, unique keys, ...) live in `protocol/validate.py` so that each error can
name the exact field and line.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, StrictInt, field_validator

from protocol_runner.protocol.expectations import ExpectationSpec


def _int_to_str(value: object) -> object:
    """Level names may be written as bare numbers in YAML (`friction: 2`): treat them as names."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return value


LevelName = Annotated[str, BeforeValidator(_int_to_str)]
Identifier = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_\-]*$", max_length=64)]


class _Model(BaseModel):
    # .inf / .nan are refused in every number field: no limit, range or time may be infinite or undefined
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _check_range(value: tuple[float, float]) -> tuple[float, float]:
    lo, hi = value
    if not lo < hi:
        raise ValueError(f"range must be [low, high] with low < high, got [{lo:g}, {hi:g}]")
    return value


RangePair = Annotated[tuple[float, float], BeforeValidator(lambda v: tuple(v) if isinstance(v, list) else v)]


# --------------------------------------------------------------------------------------------- rig


class JointSpec(_Model):
    name: Identifier
    description: str = ""
    rsst_joint: int | None = Field(default=None, ge=1, le=12)
    range_deg: RangePair
    torque_range_nm: RangePair

    _range = field_validator("range_deg", "torque_range_nm")(_check_range)


class OutputSpec(_Model):
    board: Literal["usb3105"]
    channel: int = Field(ge=0, le=15)
    rate_hz: float = Field(gt=0, le=1000)
    volts_range: RangePair = (-10.0, 10.0)
    serial: str | None = None

    _range = field_validator("volts_range")(_check_range)


class InputSpec(_Model):
    board: Literal["dt9814", "usb1608fs"]
    angle_channel: int = Field(ge=0, le=23)
    torque_channel: int = Field(ge=0, le=23)
    rate_hz: float = Field(gt=0, le=50000)
    volts_range: RangePair = (-10.0, 10.0)
    serials: list[str] = Field(default_factory=list)
    dt9814_product_id: int | None = Field(default=None, ge=0, le=0xFFFF)

    _range = field_validator("volts_range")(_check_range)


class CalibrationTablesSpec(_Model):
    command_table: str | None = None
    angle_table: str | None = None
    torque_table: str | None = None


class SafetySpec(_Model):
    max_rate_deg_s: float = Field(gt=0)
    max_accel_deg_s2: float = Field(gt=0)
    park_angle_deg: float
    park_rate_deg_s: float = Field(gt=0)


class RigSpec(_Model):
    robot: str
    joint: JointSpec
    output: OutputSpec
    input: InputSpec
    calibration: CalibrationTablesSpec = CalibrationTablesSpec()
    safety: SafetySpec
    time_constant_s: float = Field(gt=0)


class BoltTorque(_Model):
    bolts: str
    torque_ft_lb: float = Field(gt=0)


# ------------------------------------------------------------------------------------------ levels


class RangeLevel(_Model):
    range_deg: RangePair | None = None
    same_as: LevelName | None = None
    description: str = ""


class FrictionLevel(_Model):
    torque_nm: float | None = Field(default=None, ge=0)
    screw_turns: float | None = Field(default=None, ge=0)
    same_as: LevelName | None = None
    description: str = ""


class StiffnessLevel(_Model):
    n_per_mm: float | None = Field(default=None, ge=0)
    same_as: LevelName | None = None
    description: str = ""


class SpeedLevel(_Model):
    max_deg_s: float | None = Field(default=None, gt=0)
    same_as: LevelName | None = None
    description: str = ""


class PreloadLevel(_Model):
    position: int | None = Field(default=None, ge=1, le=5)
    same_as: LevelName | None = None
    description: str = ""


def _str_keys(value: object) -> object:
    if isinstance(value, dict):
        return {_int_to_str(k): v for k, v in value.items()}
    return value


class Levels(_Model):
    brace_rom: Annotated[dict[str, RangeLevel], BeforeValidator(_str_keys)]
    robot_rom: Annotated[dict[str, RangeLevel], BeforeValidator(_str_keys)]
    friction: Annotated[dict[str, FrictionLevel], BeforeValidator(_str_keys)]
    stiffness: Annotated[dict[str, StiffnessLevel], BeforeValidator(_str_keys)]
    speed: Annotated[dict[str, SpeedLevel], BeforeValidator(_str_keys)]
    preload: Annotated[dict[str, PreloadLevel], BeforeValidator(_str_keys)]


LEVEL_FAMILIES: tuple[str, ...] = ("brace_rom", "robot_rom", "friction", "stiffness", "speed", "preload")

# ------------------------------------------------------------------------------------ trajectories


class SinusoidSpec(_Model):
    periods: float = Field(gt=0)


class HumanFileSpec(_Model):
    file: str
    description: str = ""


class IdentificationSpec(_Model):
    range_deg: RangePair
    total_s: float = Field(gt=0)
    repetition_s: float = Field(gt=0)
    initial_period_s: float = Field(gt=0)
    final_period_s: float = Field(gt=0)


class CalibrationStepSpec(_Model):
    from_deg: float
    step_deg: float
    ramp_s: float = Field(ge=0)
    hold_s: float = Field(gt=0)
    settle_s: float = Field(gt=0)


class TrajectoriesSpec(_Model):
    sinusoid: SinusoidSpec
    human: dict[Identifier, HumanFileSpec] = Field(default_factory=dict)
    identification: IdentificationSpec | None = None
    calibration_step: CalibrationStepSpec


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
    # torque = backbone(angle) + z: "polynomial" (a polynomial of the angle through the loops' midline,
    # until the device elements are declared) or "none" (the thesis form, torque = z)
    backbone: Literal["polynomial", "none"] = "polynomial"
    backbone_degree: int = Field(default=9, ge=0, le=15)

    @property
    def polynomial_degree(self) -> int | None:
        """The backbone polynomial's degree, or None for the thesis form torque = z."""
        return self.backbone_degree if self.backbone == "polynomial" else None


class FitsSpec(_Model):
    spring: SpringFitSpec = SpringFitSpec()
    bouc_wen: BoucWenFitSpec = BoucWenFitSpec()


# ------------------------------------------------------------------------------------- the matrix

Profile = Literal["sinusoid", "human", "identification"]


class ConfigurationSpec(_Model):
    key: StrictInt = Field(ge=1)
    run: StrictInt = Field(ge=1)
    profile: Profile
    trajectory: Identifier | None = None
    brace_rom: LevelName
    robot_rom: LevelName
    friction: LevelName
    stiffness: LevelName
    speed: LevelName
    preload: LevelName
    trials: StrictInt = Field(ge=1, le=50)


class SetSpec(_Model):
    name: Identifier
    condition: str
    configurations: list[ConfigurationSpec] = Field(min_length=1)


ComparisonParameter = Literal[
    "speed", "brace_rom", "robot_rom", "friction", "stiffness", "preload", "profile"
]


class ComparisonSpec(_Model):
    name: Identifier
    parameter: ComparisonParameter
    section: str = ""
    title: str
    configurations: list[StrictInt] = Field(min_length=2)


class PredictionSpec(_Model):
    """A Bouc-Wen model fitted on configuration `fit` predicts configuration `predict` (the same device
    elements at another speed or range); the report gives the prediction's RMSE."""

    fit: StrictInt
    predict: StrictInt
    note: str = ""


class ReportSpec(_Model):
    reference_dataset: str | None = None
    comparisons: list[ComparisonSpec] = Field(default_factory=list)
    predictions: list[PredictionSpec] = Field(default_factory=list)


class Protocol(_Model):
    """A whole campaign (one protocol file)."""

    schema_version: Literal[1]
    name: Identifier
    title: str = ""
    description: str = ""
    rig: RigSpec
    bolt_torques: list[BoltTorque] = Field(default_factory=list)
    levels: Levels
    trajectories: TrajectoriesSpec
    calibration_check: CalibrationCheckSpec
    processing: ProcessingSpec
    fits: FitsSpec = FitsSpec()
    sets: list[SetSpec] = Field(min_length=1)
    report: ReportSpec = ReportSpec()
    expectations: list[ExpectationSpec] = Field(default_factory=list)

    def configurations(self) -> list[tuple[SetSpec, ConfigurationSpec]]:
        """Every configuration with its set, in execution order."""
        return [(s, c) for s in self.sets for c in s.configurations]
