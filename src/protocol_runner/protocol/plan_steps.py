"""The Plan's data: one frozen dataclass per step kind, and the Plan (steps in execution order, by id).

A step's JSON (`run-protocol --plan --json`, the journal) is its fields in declaration order after `id` and
`kind`: tuples as lists, records by their own `to_json`, None left out; a kind adds or renames keys only
where its JSON differs from its fields (the trajectories of a multi-joint step, a trial's device).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Any, ClassVar

from .plan_trajectory import Trajectory
from .settings import Settings


def _plain(value: Any) -> Any:
    """A field's JSON value: tuples as lists (recursively), records by their `to_json`."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "to_json"):
        return value.to_json()
    return value


@dataclass(frozen=True)
class Step:
    id: str
    kind: str

    #: fields a kind writes itself (or not at all) in its `to_json`
    _NOT_PLAIN: ClassVar[tuple[str, ...]] = ()

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

_TRAJECTORY_FIELDS = ("trajectory", "joint_trajectories")


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

    def joints_names(self) -> tuple[str, ...]:
        """The joints checked one after the other (multi-joint; empty for one joint)."""
        return tuple(j for j, _ in self.joint_trajectories)

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


@dataclass(frozen=True)
class FitStep(Step):
    set: str
    configuration: int
    models: tuple[str, ...]


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


@dataclass(frozen=True)
class ReportStep(Step):
    pass


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

    def __len__(self) -> int:
        return len(self.steps)

    @property
    def robot_time_s(self) -> float:
        return sum(s.robot_time_s for s in self.steps)

    def of_kind(self, kind: type[Step]) -> list[Any]:
        return [s for s in self.steps if isinstance(s, kind)]
