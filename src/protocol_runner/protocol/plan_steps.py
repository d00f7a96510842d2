"""The Plan's data: one frozen dataclass per step kind, and the Plan (steps in execution order, by id).

Each kind's class declares what the rest of the program needs to know of it (`describe`, `inputs`,
`uses_rig`, `background`: docs/architecture.md "a step kind"); the function that runs it is registered in
`steps/registry.py`. A step's JSON (`run-protocol --plan --json`, the journal) is its fields in declaration
order after `id` and `kind`: tuples as lists, records by their own `to_json`, None left out; a kind adds or
renames keys only where its JSON differs from its fields (the trajectories of a multi-joint step, a trial's
device).
"""

from __future__ import annotations

import dataclasses
import json
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

from .settings import Settings
from .step_ids import step_id
from .trajectory_record import Trajectory
from .trajectory_specs import trajectory_kind


def _plain(value: Any) -> Any:
    """A field's JSON value: tuples as lists (recursively), records by their `to_json`."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "to_json"):
        return value.to_json()
    return value


@dataclass(frozen=True)
class Step(ABC):
    id: str
    kind: str

    #: fields a kind writes itself (or not at all) in its `to_json`
    _NOT_PLAIN: ClassVar[tuple[str, ...]] = ()
    #: a step of the kind moves the joint or sets the rig up (a resume asks for the rig's state first)
    uses_rig: ClassVar[bool] = False
    #: a step of the kind only reads finished units: it may run in an analysis worker beside the trials
    background: ClassVar[bool] = False

    @abstractmethod
    def describe(self) -> str:
        """What the step does: its line in the plan table (`run-protocol --plan`), and any further lines
        (after a newline) shown below it, indented under the first."""

    def inputs(self) -> tuple[str, ...]:
        """The ids of the earlier steps whose units this step reads: a resume that redoes one of them (its
        unit was lost) redoes this step too, from the new unit."""
        return ()

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id, "kind": self.kind}
        for f in dataclasses.fields(self)[2:]:
            value = getattr(self, f.name)
            if f.name not in self._NOT_PLAIN and value is not None:
                out[f.name] = _plain(value)
        return out

    @property
    def robot_time_s(self) -> float:
        """Time the robot moves during this step (for ETAs); 0 for steps that do not move it."""
        return 0.0


JointTrajectories = tuple[tuple[str, Trajectory], ...]
"""(joint, trajectory) per driven joint of a multi-joint protocol, in channel order."""
JointTexts = tuple[tuple[str, str], ...]
"""(joint, text) per driven joint, in channel order."""

_TRAJECTORY_FIELDS = ("trajectory", "joint_trajectories")

JOINTS_INLINE_WIDTH = 100
"""The longest per-joint text a plan-table line holds; a longer one is shown a line per joint below it."""


def _with_joints(line: str, what: JointTexts, after: str = "", *, group: bool = True) -> str:
    """`line`, what each driven joint does, then `after`, for the plan table: the "joint: what" parts on
    the line when short, else one part per line below it (the lines separated by newlines). With `group`,
    joints doing the same thing are named together ("every joint" when all do); without, each joint in
    channel order."""
    if group:
        joints_of: dict[str, list[str]] = {}
        for joint, text in what:
            joints_of.setdefault(text, []).append(joint)
        every = len(what) > 1
        parts = [
            f"{'every joint' if every and len(js) == len(what) else ', '.join(js)}: {text}"
            for text, js in joints_of.items()
        ]
    else:
        parts = [f"{joint}: {text}" for joint, text in what]
    inline = "; ".join(parts)
    if len(inline) <= JOINTS_INLINE_WIDTH:
        return f"{line}{inline}{after}"
    return "\n".join([f"{line}per joint below{after}", *parts])


def _trajectory_json(trajectory: Trajectory, per_joint: JointTrajectories) -> dict[str, Any]:
    """The plan's `joints` and `trajectory` keys: one trajectory, or one per joint (multi-joint)."""
    if not per_joint:
        return {"trajectory": trajectory.to_json()}
    return {"joints": [j for j, _ in per_joint], "trajectory": {j: t.to_json() for j, t in per_joint}}


@dataclass(frozen=True)
class CalibrationCheckStep(Step):
    set: str
    when: str  # "before" / "after"
    trajectory: Trajectory
    # multi-joint: each joint's own step, run one joint after the other (the others held at park)
    joint_trajectories: JointTrajectories = ()

    _NOT_PLAIN: ClassVar[tuple[str, ...]] = _TRAJECTORY_FIELDS
    uses_rig: ClassVar[bool] = True

    def describe(self) -> str:
        """The step of the joint (single joint), or each joint's step from its start angle, one joint after
        the other (multi-joint)."""
        if not self.joint_trajectories:
            step_deg = dict(self.trajectory.params).get("step_deg", 0.0)
            return f"set {self.set}: {step_deg:g} deg step check {self.when}"
        steps = tuple(
            (j, f"{t.number('step_deg'):g} deg step from {t.number('from_deg'):g} deg")
            for j, t in self.joint_trajectories
        )
        line = f"set {self.set}: step check {self.when}, one joint after the other: "
        return _with_joints(line, steps, group=False)

    def to_json(self) -> dict[str, Any]:
        return {**super().to_json(), **_trajectory_json(self.trajectory, self.joint_trajectories)}

    @property
    def robot_time_s(self) -> float:
        if self.joint_trajectories:
            return sum(t.duration_s for _, t in self.joint_trajectories)
        return self.trajectory.duration_s


@dataclass(frozen=True)
class ChecklistStep(Step):
    set: str
    title: str
    items: tuple[str, ...]
    brace: str  # the brace state after this checklist: "on" / "off"
    configuration: int | None = None
    settings: Settings | None = None

    uses_rig: ClassVar[bool] = True

    def describe(self) -> str:
        return self.title


@dataclass(frozen=True)
class TrialStep(Step):
    set: str
    configuration: int
    run: int
    trial: int
    brace: str  # "on" / "off"
    settings: Settings
    trajectory: Trajectory
    twin: str | None = None  # brace-off trials: the id of the brace-on trial whose output they follow
    # multi-joint: every driven joint's motion (`trajectory` is then the first joint's)
    joint_trajectories: JointTrajectories = ()

    _NOT_PLAIN: ClassVar[tuple[str, ...]] = (*_TRAJECTORY_FIELDS, "twin")
    uses_rig: ClassVar[bool] = True

    def describe(self) -> str:
        """The trial, its levels and its motion: its trajectory's, or every driven joint's (multi-joint)."""
        line = (
            f"config {self.configuration:>2} run {self.run:>2} trial {self.trial} brace {self.brace:<3}  "
            f"{' '.join(f.level for _, f in self.settings.factors)}  "
        )
        extra = f"  (input from {self.twin})" if self.twin else ""
        motions = self.joint_trajectories or (("", self.trajectory),)
        described = tuple((j, trajectory_kind(t.profile).describe(t)) for j, t in motions)
        if not self.joint_trajectories:
            return f"{line}{described[0][1]}{extra}"
        return _with_joints(line, described, extra)

    def inputs(self) -> tuple[str, ...]:
        """A brace-off trial commands what its brace-on twin measured."""
        return (self.twin,) if self.twin is not None else ()

    @property
    def joints(self) -> tuple[str, ...]:
        """The driven joints of a multi-joint trial, in channel order (empty for one joint)."""
        return tuple(j for j, _ in self.joint_trajectories)

    def to_json(self) -> dict[str, Any]:
        out = {**super().to_json(), **_trajectory_json(self.trajectory, self.joint_trajectories)}
        if self.brace == "on":
            out["device"] = self.settings.device_json()
        if self.twin is not None:
            out["derived_from"] = self.twin
        return out

    @property
    def robot_time_s(self) -> float:
        return self.trajectory.duration_s


@dataclass(frozen=True)
class ProcessStep(Step):
    set: str
    configuration: int
    trials: tuple[tuple[str, str], ...]  # (brace-on id, brace-off id) per trial

    background: ClassVar[bool] = True

    def describe(self) -> str:
        return f"config {self.configuration}: transition, filter, equal-angle subtraction, cycles, energy"

    def inputs(self) -> tuple[str, ...]:
        """Both trials of each pair."""
        return tuple(i for pair in self.trials for i in pair)


@dataclass(frozen=True)
class FitStep(Step):
    set: str
    configuration: int
    models: tuple[str, ...]

    background: ClassVar[bool] = True

    def describe(self) -> str:
        return f"config {self.configuration}: fit {', '.join(self.models)}"

    def inputs(self) -> tuple[str, ...]:
        """The configuration's processing (the loops it stored)."""
        return (step_id("process", key=self.configuration),)


@dataclass(frozen=True)
class Comparison:
    """A declared group of configurations that differ by `parameter` (a declared factor's name, or
    "trajectory"): the plan's compare step, and the archive's `/comparisons/<name>` the report reads."""

    name: str
    parameter: str
    title: str
    section: str
    configurations: tuple[int, ...]


@dataclass(frozen=True)
class CompareStep(Comparison, Step):
    """The comparison of a protocol's `report.comparisons` entry (its fields after `id` and `kind`)."""

    def describe(self) -> str:
        return f"{self.title} (§{self.section}): configurations {', '.join(map(str, self.configurations))}"

    def inputs(self) -> tuple[str, ...]:
        """The processing of each of its configurations."""
        return tuple(step_id("process", key=key) for key in self.configurations)


@dataclass(frozen=True)
class ReportStep(Step):
    """The session's end: the archive consolidated, then the HTML report (the runner's own step)."""

    def describe(self) -> str:
        return "HTML report"


@dataclass(frozen=True)
class Plan:
    protocol_name: str
    protocol_sha256: str
    steps: tuple[Step, ...]
    only: tuple[int, ...] = ()
    _index: dict[str, int] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._index.update({s.id: i for i, s in enumerate(self.steps)})

    def to_json(self) -> dict[str, Any]:
        return {
            "protocol": self.protocol_name,
            "protocol_sha256": self.protocol_sha256,
            "steps": [s.to_json() for s in self.steps],
        }

    def dumps(self) -> str:
        return json.dumps(self.to_json(), indent=2)

    def step(self, step_id: str) -> Step:
        return self.steps[self._index[step_id]]

    def __contains__(self, step_id: object) -> bool:
        """Whether the plan has a step of this id."""
        return step_id in self._index

    def __len__(self) -> int:
        return len(self.steps)

    @property
    def robot_time_s(self) -> float:
        return sum(s.robot_time_s for s in self.steps)
