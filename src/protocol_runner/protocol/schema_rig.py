"""The resolved rig of a protocol (rig file + joint + overrides, docs/protocol.md "Rig"): pydantic models."""

from __future__ import annotations

from pydantic import Field, field_validator

from protocol_runner.protocol.schema_base import Identifier, RangePair, _check_range, _Model

# --------------------------------------------------------------------------------------------- rig
# The resolved rig (rig file + joint + rig_overrides, protocol/rig_file.py): what `protocol.rig` returns.


class JointSpec(_Model):
    name: Identifier
    description: str = ""
    rsst_joint: int | None = Field(default=None, ge=1)
    range_deg: RangePair
    torque_range_nm: RangePair

    _range = field_validator("range_deg", "torque_range_nm")(_check_range)


class OutputSpec(_Model):
    board: str
    channel: int = Field(ge=0)
    rate_hz: float = Field(
        gt=0, le=1000
    )  # the protocol's output rate (the board's, or lowered by rig_overrides)
    volts_range: RangePair = (-10.0, 10.0)
    serial: str | None = None
    report_time_s: float | None = Field(default=None, gt=0)  # one output report on the wire (rig file)

    _range = field_validator("volts_range")(_check_range)


class InputSpec(_Model):
    board: str
    angle_channel: int = Field(ge=0)
    torque_channel: int = Field(ge=0)
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
    simulator: tuple[tuple[str, float], ...] = ()  # the joint's simulator parameters (rig file)
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

    _range = field_validator("range_deg")(lambda v: v if v is None else _check_range(v))


class RigOverrides(_Model):
    output_rate_hz: float | None = Field(default=None, gt=0)  # at most the output board's rate_hz
    input_board: str | None = None
    input_serials: list[str] | None = None
    joints: dict[str, JointOverride] = Field(default_factory=dict)


class BoltTorque(_Model):
    bolts: str
    torque_ft_lb: float = Field(gt=0)
