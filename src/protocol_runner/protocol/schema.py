"""The protocol file's schema (schema_version 2): pydantic models, immutable, unknown keys rejected.

Nothing here names a campaign: factors, their levels and quantities, the device's elements and the
trajectories are whatever the file declares (docs/protocol.md is the reference). Cross-field checks
(levels that exist, bindings whose units match, ranges inside the joint's range, unique keys, ...) live in
`protocol/validate.py` and `protocol/resolve.py` so that each error can name the exact field and line.
The trajectory kinds are `protocol/trajectory_specs.py`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    StrictInt,
    Tag,
    model_validator,
)

from protocol_runner.protocol.expectations import ExpectationSpec, RepeatabilitySpec
from protocol_runner.protocol.trajectory_specs import RampedStepFields, TrajectorySpec, holds_trajectories
from protocol_runner.protocol.units import compound_unit_problem, known_suffixes, unit_suffix


def _int_to_str(value: object) -> object:
    """Level names may be written as bare numbers in YAML (`friction: 2`): treat them as names."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return value


def _str_keys(value: object) -> object:
    """A mapping whose keys are level names: bare-number keys become names."""
    if isinstance(value, dict):
        return {_int_to_str(k): v for k, v in value.items()}
    return value


LevelName = Annotated[str, BeforeValidator(_int_to_str)]
Identifier = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_\-]*$", max_length=64)]


class _Model(BaseModel):
    # .inf / .nan are refused in every number field: no limit, range or time may be infinite or undefined
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _as_tuple(value: object) -> object:
    return tuple(value) if isinstance(value, list) else value


def _check_range(value: tuple[float, float]) -> tuple[float, float]:
    lo, hi = value
    if not lo < hi:
        raise ValueError(f"range must be [low, high] with low < high, got [{lo:g}, {hi:g}]")
    return value


RangePair = Annotated[tuple[float, float], BeforeValidator(_as_tuple), AfterValidator(_check_range)]
"""[low, high] with low < high."""


class JointSpec(_Model):
    name: Identifier
    description: str = ""
    rsst_joint: int | None = Field(default=None, ge=1)
    range_deg: RangePair
    torque_range_nm: RangePair


Backend = Literal["pyusb", "uldaq", "mcculw"]
"""Which library drives a board: pyusb (the drivers of this package), MCC's uldaq or mcculw."""


class OutputSpec(_Model):
    board: str
    channel: int = Field(ge=0)
    # the protocol's output rate (the board's, or lowered by rig_overrides)
    rate_hz: float = Field(gt=0, le=1000)
    volts_range: RangePair = (-10.0, 10.0)
    serial: str | None = None
    report_time_s: float | None = Field(default=None, gt=0)  # one output report on the wire (rig file)
    backend: Backend = "pyusb"  # the rig file's board: which library drives it (docs/hardware.md)


class InputSpec(_Model):
    board: str
    angle_channel: int = Field(ge=0)
    torque_channel: int = Field(ge=0)
    rate_hz: float = Field(gt=0, le=50000)
    volts_range: RangePair = (-10.0, 10.0)
    serials: list[str] = Field(default_factory=list)
    dt9814_product_id: int | None = Field(default=None, ge=0, le=0xFFFF)
    backend: Backend = "pyusb"


class CalibrationTablesSpec(_Model):
    command_table: str | None = None
    angle_table: str | None = None
    torque_table: str | None = None


class SafetySpec(_Model):
    max_rate_deg_s: float = Field(gt=0)
    max_accel_deg_s2: float = Field(gt=0)
    park_angle_deg: float
    park_rate_deg_s: float = Field(gt=0)


class WatchdogOverride(_Model):
    """A protocol's `watchdog:` (or a rig file's `joint_defaults.watchdog`): each key optional, the rest
    from the rig file, else the built-in defaults of `WatchdogSpec`."""

    torque_margin: float | None = Field(default=None, gt=0, le=1)
    max_tracking_error_deg: float | None = Field(default=None, gt=0)
    max_tracking_error_s: float | None = Field(default=None, gt=0)


class WatchdogSpec(_Model):
    """The watchdog on a joint's measured signals (hardware/watchdog.py): the measured torque within
    `torque_margin` x the joint's torque range; the measured angle within `max_tracking_error_deg` of the
    command delayed by the servo lag, except for excursions shorter than `max_tracking_error_s`. The
    defaults are the RSST rig file's (rigs/rsst.yaml says how they were chosen)."""

    torque_margin: float = Field(default=1.0, gt=0, le=1)
    max_tracking_error_deg: float = Field(default=45.0, gt=0)
    max_tracking_error_s: float = Field(default=3.0, gt=0)

    def merged(self, over: WatchdogOverride | None) -> WatchdogSpec:
        """These values with the keys `over` gives replaced."""
        if over is None:
            return self
        return self.model_copy(update={k: v for k, v in over.model_dump().items() if v is not None})


class RigSpec(_Model):
    """A driven joint's resolved rig (rig file + joint + rig_overrides, protocol/rig_file.py)."""

    robot: str
    joint: JointSpec
    output: OutputSpec
    input: InputSpec
    calibration: CalibrationTablesSpec = CalibrationTablesSpec()
    safety: SafetySpec
    time_constant_s: float = Field(gt=0)
    simulator: tuple[tuple[str, float], ...] = ()  # the joint's simulator parameters (rig file)
    watchdog: WatchdogSpec = WatchdogSpec()  # the rig file's joint_defaults.watchdog over the built-in ones
    rig_file: str = ""
    rig_sha256: str = ""


class SafetyOverride(_Model):
    max_rate_deg_s: float | None = Field(default=None, gt=0)
    max_accel_deg_s2: float | None = Field(default=None, gt=0)
    park_angle_deg: float | None = None
    park_rate_deg_s: float | None = Field(default=None, gt=0)


class JointOverride(_Model):
    calibration: CalibrationTablesSpec = CalibrationTablesSpec()
    safety: SafetyOverride | None = None
    range_deg: RangePair | None = None


class RigOverrides(_Model):
    output_rate_hz: float | None = Field(default=None, gt=0)  # at most the output board's rate_hz
    input_board: str | None = None
    input_serials: list[str] | None = None
    joints: dict[str, JointOverride] = Field(default_factory=dict)


class BoltTorque(_Model):
    bolts: str
    torque_ft_lb: float = Field(gt=0)


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


Factor = Annotated[dict[str, LevelSpec], BeforeValidator(_str_keys), Field(min_length=1)]


class ElementSpec(_Model):
    """One element of the device: `name`, `type` (models/element_types.py ELEMENT_TYPES) and its parameters,
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


RESERVED_CONFIGURATION_KEYS = ("key", "run", "trajectory", "trials", "description")
MAX_KEY = 999_999  # a key or run number: ample, and an integer every archive attribute and MATLAB field holds


class ConfigurationSpec(_Model):
    """An explicit row: reserved keys, and `<factor>: <level label>` for the factors it sets."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    key: StrictInt = Field(ge=1, le=MAX_KEY)
    run: StrictInt = Field(ge=1, le=MAX_KEY)
    trajectory: Identifier
    trials: StrictInt = Field(ge=1, le=50)
    description: str = ""

    @model_validator(mode="before")
    @classmethod
    def _labels(cls, data: Any) -> Any:
        if isinstance(data, dict):
            data = {k: (v if k in RESERVED_CONFIGURATION_KEYS else _int_to_str(v)) for k, v in data.items()}
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


class ComparisonSpec(_Model):
    name: Identifier
    parameter: Identifier  # a declared factor, or "trajectory" (checked in validate.py)
    section: str = ""
    title: str
    configurations: list[StrictInt] = Field(min_length=2)
    # explicit (a, b) pairs for the Differences table (b minus a), e.g. a paired design; else adjacent ones
    pairs: list[Annotated[tuple[StrictInt, StrictInt], BeforeValidator(_as_tuple)]] | None = Field(
        default=None, min_length=1
    )

    @model_validator(mode="after")
    def _pairs_compared(self) -> ComparisonSpec:
        for a, b in self.pairs or ():
            for key in (a, b):
                if key not in self.configurations:
                    raise ValueError(
                        f"pair ({a}, {b}): configuration {key} is not in this comparison's configurations"
                    )
            if a == b:
                raise ValueError(f"pair ({a}, {b}) compares a configuration with itself")
        return self


class PredictionSpec(_Model):
    """A Bouc-Wen model fitted on configuration `fit` predicts configuration `predict` (the same device
    elements at another speed or range); the report gives the prediction's RMSE."""

    fit: StrictInt
    predict: StrictInt
    note: str = ""


class CitationsSpec(_Model):
    """Where a source (e.g. a thesis) shows what a part of the report shows: each text is printed beside
    that part ("as <text>"). All optional: a campaign that reproduces no source cites nothing."""

    configurations: str = ""  # the per-configuration loops
    comparisons: str = ""  # the overlaid loops of each comparison
    energy: str = ""  # energy per cycle against the compared factor
    reference: str = ""  # the reference datasets
    models: str = ""  # the models section as a whole
    elements: str = ""  # the elastic elements fitted to the loops' midline
    bouc_wen: str = ""  # the Bouc-Wen model against the data
    matrix: str = ""  # the test matrix
    calibration: str = ""  # the calibration step checks


class ReportSpec(_Model):
    reference_dataset: str | None = None
    citations: CitationsSpec = CitationsSpec()
    comparisons: list[ComparisonSpec] = Field(default_factory=list)
    predictions: list[PredictionSpec] = Field(default_factory=list)
    repeatability: list[RepeatabilitySpec] = Field(default_factory=list)


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
    watchdog: WatchdogOverride | None = None  # over the rig file's joint_defaults.watchdog, every joint

    _rigs: tuple[RigSpec, ...] = PrivateAttr(default=())

    @model_validator(mode="after")
    def _joint_or_joints(self) -> Any:
        if (self.joint is None) == (self.joints is None):
            raise ValueError("give exactly one of `joint` (one driven joint) and `joints` (several)")
        return self  # a joint listed twice in `joints` is refused at its entry (rig_file.resolve_rigs)

    @property
    def multi_joint(self) -> bool:
        """True when the protocol names `joints:` (even one): trials drive a set of joints."""
        return self.joints is not None

    @property
    def rig(self) -> RigSpec:
        """The resolved rig of the driven joint (set by the loader); of a multi-joint protocol, the first
        driven joint's in channel order (`rigs` has every joint's)."""
        return self.rigs[0]

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


# The protocol file's JSON Schema, for editors (docs/protocol.md "Editor set-up"): generated from the models
# above, so it cannot drift from what `--validate` accepts field by field; cross-field checks are left to
# `--validate`. A copy ships in the package; `run-protocol --schema` prints the same text.

SCHEMA_FILE = Path(__file__).resolve().parent.parent / "schemas" / "protocol.schema.json"
"""The schema as shipped with the package."""


def protocol_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a protocol file."""
    schema = Protocol.model_json_schema()
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "protocol-runner campaign file",
        **{k: v for k, v in schema.items() if k != "title"},
    }


def protocol_json_schema_text() -> str:
    """The schema as the text shipped and printed (sorted keys, two-space indent, a final newline)."""
    return json.dumps(protocol_json_schema(), indent=2, sort_keys=True, ensure_ascii=False) + "\n"
