"""Rig files (`src/protocol_runner/rigs/*.yaml`): a robot's joints, boards and channels, and the per-joint
dynamics and simulator parameters, shared by every protocol that names the rig (`rig: rsst`).

A protocol names a rig (a shipped name, or a path relative to its folder) and its joints; `resolve_rig`
merges each joint with the rig's `joint_defaults` and the protocol's `rig_overrides` into the `RigSpec`
the rest of the runner reads (`protocol.rig.joint`, `.output`, `.input`, `.safety`, `.simulator`, ...).
Mistakes in the rig file (an unknown key, a bad range, two joints on one channel, an unknown simulator
parameter) name the rig file, its line and the field.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from pydantic import Field

from ..errors import InvalidInput
from ..resources import packaged_rigs_dir
from ..tables import read_table_text
from .loaded import Loc, Problem, RigSource
from .paths import OutsideFolder, confined_path
from .resolve import joints_named
from .schema import (
    Backend,
    Identifier,
    InputSpec,
    JointOverride,
    JointSpec,
    OutputSpec,
    RangePair,
    RigOverrides,
    RigSpec,
    SafetyOverride,
    SafetySpec,
    WatchdogOverride,
    WatchdogSpec,
    _Model,
)
from .yaml_doc import format_problems, parse_yaml, validated

if TYPE_CHECKING:
    from ..hardware.discovery import OutputTiming


class BoardSpec(_Model):
    role: Literal["output", "input"]
    channels: int = Field(ge=1, le=64)
    resolution_bits: int = Field(ge=1, le=32)
    volts_range: RangePair = (-10.0, 10.0)
    rate_hz: float = Field(gt=0, le=50000)
    serials: list[str] = Field(default_factory=list)
    product_id: int | None = Field(default=None, ge=0, le=0xFFFF)
    # an output board's time for one output report (a tick of N joints sends N + 1: docs/hardware.md)
    report_time_s: float | None = Field(default=None, gt=0, le=1)
    # which library drives the board: pyusb (this package's drivers), MCC's uldaq or mcculw
    backend: Backend = "pyusb"


class JointDefaults(_Model):
    time_constant_s: float = Field(gt=0)
    safety: SafetyOverride = SafetyOverride()
    simulator: dict[str, float] = Field(default_factory=dict)
    watchdog: WatchdogOverride | None = None


class RigJoint(_Model):
    number: int = Field(ge=1)
    description: str = ""
    range_deg: RangePair
    torque_range_nm: RangePair
    output_channel: int = Field(ge=0)
    angle_channel: int = Field(ge=0)
    torque_channel: int = Field(ge=0)
    time_constant_s: float | None = Field(default=None, gt=0)
    safety: SafetyOverride = SafetyOverride()
    simulator: dict[str, float] = Field(default_factory=dict)


class RigFile(_Model):
    schema_version: Literal[1]
    robot: str
    description: str = ""
    boards: dict[Identifier, BoardSpec] = Field(min_length=1)
    output_board: str
    input_board: str
    joint_defaults: JointDefaults
    joints: dict[Identifier, RigJoint] = Field(min_length=1)


@dataclass(frozen=True, kw_only=True)
class LoadedRig(RigSource):
    """A checked rig file: its source, and the rig it declares."""

    rig: RigFile = field(repr=False, compare=False)


def is_rig_path(name_or_path: str) -> bool:
    """Whether a protocol's `rig:` names a file beside it (`lab_rig.yaml`) rather than a shipped rig (`rsst`)."""
    return "/" in name_or_path or "\\" in name_or_path or name_or_path.endswith((".yaml", ".yml"))


def find_rig(name_or_path: str, base_dir: Path) -> Path:
    """A shipped rig by name (`rsst`), or a rig file relative to the protocol's folder."""
    if not is_rig_path(name_or_path):
        path = packaged_rigs_dir() / f"{name_or_path}.yaml"
        if not path.is_file():
            known = ", ".join(sorted(p.stem for p in packaged_rigs_dir().glob("*.yaml")))
            raise InvalidInput(f"unknown rig {name_or_path!r} (shipped rigs: {known}; or give a path)")
        return path
    try:
        path = confined_path(base_dir, name_or_path)
    except OutsideFolder as exc:
        raise InvalidInput(str(exc)) from None
    if not path.is_file():
        raise InvalidInput(f"rig file {name_or_path} not found (looked in {path.parent})")
    return path


def load_rig(path: Path, shown: str | None = None) -> LoadedRig:
    """Read and check a rig file; InvalidInput naming the rig file, line and field."""
    shown = shown or path.name
    text = read_table_text(path, "rig file")  # a regular file of bounded size, UTF-8; or InvalidInput
    return parse_rig_text(text, path, shown)


def parse_rig_text(text: str, path: Path, shown: str) -> LoadedRig:
    """Check a rig file's text (as read from `path`, or as archived in `/rig`); InvalidInput naming `shown`,
    the line and the field."""
    data, lines = parse_yaml(text, shown)
    if not isinstance(data, dict):
        raise InvalidInput(f"{shown}:1: a rig file is a mapping (schema_version, robot, boards, joints, ...)")
    rig = validated(RigFile, data, shown, lines)
    problems = list(check_rig_file(rig))
    if problems:
        raise InvalidInput(format_problems(shown, lines, problems))
    sha = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return LoadedRig(rig=rig, path=path, shown=shown, sha256=sha, lines=lines, text=text)


def output_timing(loaded: LoadedRig) -> OutputTiming:
    """What `--hardware-check` compares its measured output report time with: the output board's
    `report_time_s` and rate, and the output channels the rig's joints are wired to (its timing writes use
    another)."""
    from ..hardware.discovery import OutputTiming

    board = loaded.rig.boards[loaded.rig.output_board]
    channels = frozenset(j.output_channel for j in loaded.rig.joints.values())
    return OutputTiming(loaded.shown, board.report_time_s, board.rate_hz, channels)


def shipped_rig(name: str) -> LoadedRig:
    """A rig shipped with the runner (`rsst`), named in messages as `rigs/<name>.yaml`."""
    return load_rig(find_rig(name, packaged_rigs_dir()), shown=f"rigs/{name}.yaml")


# Board rates (Hz): the output is paced by software, one command per tick (100 Hz); the input
# scans at least 10 times a second so that a calibration step's 0.6 s ramp is sampled, and its two channels
# (angle, torque) at most 50,000 samples/s in all (the DT9814's limit; a faster rate failed only at the run).
BOARD_RATES_HZ = {"output": (1.0, 1000.0), "input": (10.0, 25000.0)}


def check_rig_file(rig: RigFile) -> Iterator[Problem]:
    from ..hardware.simulator.params import SimulatorParams, bound_problem

    for key, role in (("output_board", "output"), ("input_board", "input")):
        name = getattr(rig, key)
        board = rig.boards.get(name)
        if board is None:
            yield (key,), f"unknown board {name!r} (boards: {', '.join(rig.boards)})"
        elif board.role != role:
            yield (key,), f"board {name!r} is an {board.role} board"
    out_channels = max((b.channels for b in rig.boards.values() if b.role == "output"), default=0)
    in_channels = min((b.channels for b in rig.boards.values() if b.role == "input"), default=0)
    allowed = tuple(f.name for f in dataclasses.fields(SimulatorParams))
    where: Loc
    for where, values in (
        (("joint_defaults",), rig.joint_defaults.simulator),
        *((("joints", n), j.simulator) for n, j in rig.joints.items()),
    ):
        for param, value in values.items():
            if param not in allowed:
                yield (
                    (*where, "simulator", param),
                    f"unknown simulator parameter (known: {', '.join(allowed)})",
                )
            elif bounded := bound_problem(param, value):
                yield (*where, "simulator", param), bounded
    for name, board in rig.boards.items():
        if name == "dt9814" and board.backend != "pyusb":
            yield (
                ("boards", name, "backend"),
                f"MCC's {board.backend} does not drive the DT9814; only the pyusb backend knows it",
            )
        if board.role == "output" and board.report_time_s is None:
            yield (
                ("boards", name),
                "an output board states report_time_s, the time one output report takes (a tick of "
                "N joints sends N + 1 reports); measure it with run-protocol --hardware-check",
            )
        low, high = BOARD_RATES_HZ[board.role]
        if not low <= board.rate_hz <= high:
            yield (
                ("boards", name, "rate_hz"),
                f"an {board.role} board's rate must lie in [{low:g}, {high:g}] Hz, got {board.rate_hz:g}",
            )
    numbers: dict[int, str] = {}
    outputs: dict[int, str] = {}
    inputs: dict[int, str] = {}
    for name, j in rig.joints.items():
        loc: Loc = ("joints", name)
        lo, hi = j.torque_range_nm
        if not lo < 0.0 < hi:
            yield (
                (*loc, "torque_range_nm"),
                f"the load cell's range must include 0 N·m (a joint at rest reads 0), got [{lo:g}, {hi:g}]",
            )
        if j.number in numbers:
            yield (*loc, "number"), f"joint number {j.number} is already {numbers[j.number]}'s"
        numbers.setdefault(j.number, name)
        if j.output_channel >= out_channels:
            yield (*loc, "output_channel"), f"the output board has channels 0-{out_channels - 1}"
        elif j.output_channel in outputs:
            yield (
                (*loc, "output_channel"),
                f"output channel {j.output_channel} is already {outputs[j.output_channel]}'s",
            )
        outputs.setdefault(j.output_channel, name)
        for fld in ("angle_channel", "torque_channel"):
            ch = getattr(j, fld)
            if ch >= in_channels:
                yield (*loc, fld), f"the input boards have channels 0-{in_channels - 1}"
            elif ch in inputs:
                yield (*loc, fld), f"input channel {ch} is already used by {inputs[ch]}"
            inputs.setdefault(ch, f"{name}.{fld}")
        safety = _merged_safety(rig, j)
        for fld, value in safety.model_dump().items():
            if value is None:
                yield (*loc, "safety", fld), "missing (here or in joint_defaults.safety)"
        park = safety.park_angle_deg
        if park is not None and not j.range_deg[0] <= park <= j.range_deg[1]:
            yield (
                (*loc, "safety", "park_angle_deg"),
                f"{park:g} deg is outside the joint's range_deg {_fmt(j.range_deg)}",
            )


def _merged_safety(rig: RigFile, joint: RigJoint) -> SafetyOverride:
    base = rig.joint_defaults.safety.model_dump()
    base.update({k: v for k, v in joint.safety.model_dump().items() if v is not None})
    return SafetyOverride(**base)


def _fmt(rng: tuple[float, float]) -> str:
    return f"[{rng[0]:g}, {rng[1]:g}] deg"


def resolve_rig(
    loaded: LoadedRig, joint_name: str, overrides: RigOverrides
) -> tuple[RigSpec | None, list[Problem]]:
    """A driven joint's RigSpec: the rig file's joint merged with its defaults and the protocol's overrides
    (problems located in the PROTOCOL: `joint`, `rig_overrides...`; `resolve_rigs` checks which joints
    the overrides name)."""
    rig = loaded.rig
    joint = rig.joints.get(joint_name)
    if joint is None:
        return None, [
            (("joint",), f"no joint {joint_name!r} on rig {rig.robot} (joints: {', '.join(rig.joints)})")
        ]
    input_name = overrides.input_board or rig.input_board
    in_board = rig.boards.get(input_name)
    if in_board is None or in_board.role != "input":
        inputs = ", ".join(n for n, b in rig.boards.items() if b.role == "input")
        return None, [(("rig_overrides", "input_board"), f"not an input board of the rig (inputs: {inputs})")]
    over = overrides.joints.get(joint_name) or JointOverride()
    loc: Loc = ("rig_overrides", "joints", joint_name)
    problems: list[Problem] = []
    range_deg = over.range_deg or joint.range_deg
    if not (joint.range_deg[0] <= range_deg[0] and range_deg[1] <= joint.range_deg[1]):
        wider = f"{_fmt(range_deg)} is wider than the rig's {_fmt(joint.range_deg)}"
        problems.append(((*loc, "range_deg"), f"{wider} ({loaded.shown}, thesis Table 2)"))
        range_deg = joint.range_deg  # the park angle is checked against the rig's range
    safety = _merged_safety(rig, joint).model_dump()
    for fld, value in (over.safety or SafetyOverride()).model_dump().items():
        if value is not None and fld != "park_angle_deg" and value > safety[fld]:
            above = (
                f"{value:g} is above the rig's {safety[fld]:g} ({loaded.shown}): overrides may only tighten"
            )
            problems.append(((*loc, "safety", fld), above))
        elif value is not None:
            safety[fld] = value
    if not range_deg[0] <= safety["park_angle_deg"] <= range_deg[1]:
        outside = (
            f"park angle {safety['park_angle_deg']:g} deg is outside the joint's range {_fmt(range_deg)}"
        )
        problems.append((((*loc, "safety", "park_angle_deg") if over.safety else ("joint",)), outside))
    out_board = rig.boards[rig.output_board]
    output_rate_hz = overrides.output_rate_hz or out_board.rate_hz
    low = BOARD_RATES_HZ["output"][0]
    if output_rate_hz > out_board.rate_hz:
        above = (
            f"{output_rate_hz:g} Hz is above the output board {rig.output_board}'s rate_hz "
            f"{out_board.rate_hz:g} ({loaded.shown}): overrides may only lower it"
        )
        problems.append((("rig_overrides", "output_rate_hz"), above))
    elif output_rate_hz < low:
        below = f"an output rate must be at least {low:g} Hz, got {output_rate_hz:g}"
        problems.append((("rig_overrides", "output_rate_hz"), below))
    if problems:
        return None, problems
    simulator = {**rig.joint_defaults.simulator, **joint.simulator}
    spec = RigSpec(
        robot=rig.robot,
        joint=JointSpec(
            name=joint_name,
            description=joint.description,
            rsst_joint=joint.number,
            range_deg=range_deg,
            torque_range_nm=joint.torque_range_nm,
        ),
        output=OutputSpec(
            board=rig.output_board,
            channel=joint.output_channel,
            rate_hz=output_rate_hz,
            serial=out_board.serials[0] if out_board.serials else None,
            **out_board.model_dump(include={"volts_range", "report_time_s", "backend"}),
        ),
        input=InputSpec(
            board=input_name,
            angle_channel=joint.angle_channel,
            torque_channel=joint.torque_channel,
            serials=list(overrides.input_serials or in_board.serials),
            dt9814_product_id=in_board.product_id,
            **in_board.model_dump(include={"rate_hz", "volts_range", "backend"}),
        ),
        calibration=over.calibration,
        safety=SafetySpec(**safety),
        time_constant_s=joint.time_constant_s or rig.joint_defaults.time_constant_s,
        simulator=tuple(simulator.items()),
        watchdog=WatchdogSpec().merged(rig.joint_defaults.watchdog),
        rig_file=loaded.shown,
        rig_sha256=loaded.sha256,
    )
    return spec, []


def resolve_rigs(
    loaded: LoadedRig, joint_names: list[str], overrides: RigOverrides, *, multi: bool = True
) -> tuple[tuple[RigSpec, ...], list[Problem]]:
    """The driven joints' rigs (`joints: [...]`, or `joint:` when not `multi`): each resolved as
    `resolve_rig` does with its own `rig_overrides.joints.<joint>`, in output channel order. Problems are
    located at `joints[i]` (or `joint`) or `rig_overrides.joints.<joint>...`; two driven joints sharing an
    output or input channel are refused naming both."""
    problems: list[Problem] = []
    for i, name in enumerate(joint_names):
        if name in joint_names[:i]:
            problems.append(
                (("joints", i), f"{name!r} is listed twice (joints[{joint_names.index(name)}] names it)")
            )
    if problems:
        return (), problems
    specs: list[RigSpec] = []
    for i, name in enumerate(joint_names):
        own = overrides.model_copy(
            update={"joints": {k: v for k, v in overrides.joints.items() if k == name}}
        )
        spec, found = resolve_rig(loaded, name, own)
        problems += [((("joints", i) if loc == ("joint",) and multi else loc), msg) for loc, msg in found]
        if spec is not None:
            specs.append(spec)
    problems += joints_named(("rig_overrides", "joints"), overrides.joints, joint_names)
    if problems:  # a shared override's problem (the output rate) once, not once per joint
        return (), list(dict.fromkeys(problems))
    used: dict[tuple[str, int], str] = {}
    for spec in specs:
        for kind, ch in (
            ("output", spec.output.channel),
            ("input", spec.input.angle_channel),
            ("input", spec.input.torque_channel),
        ):
            other = used.get((kind, ch))
            if other is not None and other != spec.joint.name:
                where = ("joints", joint_names.index(spec.joint.name))
                problems.append(
                    (
                        where,
                        f"{spec.joint.name} and {other} use the same {kind} channel {ch} ({loaded.shown})",
                    )
                )
            used[(kind, ch)] = spec.joint.name
    return ((), problems) if problems else (tuple(sorted(specs, key=lambda s: s.output.channel)), [])
