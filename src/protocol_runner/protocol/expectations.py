"""The schema of the protocol's declared results: its `expectations:` list and the report's
`repeatability:` groups (docs/protocol.md "Expectations" and "Repeatability"), with their cross-checks."""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping, Sequence
from itertools import combinations, pairwise
from typing import Annotated, Literal

from pydantic import AliasChoices, BaseModel, BeforeValidator, ConfigDict, Field, StrictInt, model_validator

from .only import key_spans

Relation = Literal["increasing", "decreasing", "no_trend", "greater", "less", "equal", "inside"]

MetricName = Literal[
    "energy_per_cycle",
    "energy_per_degree",
    "torque_angle_slope",
    "angle_percentile",
    "range_reached",
    "peak_torque",
    "hysteresis_width",
    "fit_rmse",
]

Terms = list[tuple[float, int]]

_Pair = Annotated[tuple[float, float], BeforeValidator(lambda v: tuple(v) if isinstance(v, list) else v)]


class ExpectationSpec(BaseModel):
    """One statement a campaign expects its data to support, and how to decide it."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    id: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=31)]  # a MATLAB field name
    text: str = Field(min_length=1)
    section: str = ""
    metric: MetricName
    percentile: float | None = Field(default=None, ge=0, le=100)
    angle_deg: float | None = None
    configurations: list[StrictInt] = Field(min_length=1)
    relation: Relation
    than: list[StrictInt] | None = None
    baseline: list[StrictInt] | None = None  # pairwise with `configurations`: each minus its baseline
    than_baseline: list[StrictInt] | None = None  # pairwise with `than`: each minus its baseline
    value: float | None = None
    # equivalence margin of `equal` / `no_trend`, in the metric's unit; `tolerance` is its older name
    margin: float | None = Field(default=None, gt=0, validation_alias=AliasChoices("margin", "tolerance"))
    interval: _Pair | None = None
    min_trials: StrictInt = Field(default=2, ge=2, le=50)
    # which driven joint's data decide it: one joint, or every driven joint, each on its own (a campaign of
    # one joint needs neither)
    joint: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_\-]*$", max_length=64)] | None = None
    joints: Literal["all"] | None = None
    engages: Annotated[str, Field(min_length=1)] | None = None  # a device element the statement is about
    simulator_tuned: bool = False
    depends_on_simulator: list[Annotated[str, Field(min_length=1)]] = Field(default_factory=list)
    tuned: str = ""  # free text: which simulator choice the verdict follows from

    @property
    def depends_on_tuning(self) -> bool:
        """True when the declaration says a simulator value was chosen to reproduce this statement."""
        return self.simulator_tuned or bool(self.depends_on_simulator) or bool(self.tuned.strip())

    @property
    def named_keys(self) -> list[int]:
        """Every configuration key the statement names, each once, in first-named order."""
        named = (self.configurations, self.baseline, self.than, self.than_baseline)
        return list(dict.fromkeys(k for keys in named for k in keys or ()))

    @model_validator(mode="after")
    def _relation_fields(self) -> ExpectationSpec:
        r = self.relation
        if self.joint is not None and self.joints is not None:
            raise ValueError("give at most one of `joint` (one joint) and `joints: all` (each joint)")
        if self.metric == "angle_percentile" and self.percentile is None:
            raise ValueError("metric angle_percentile needs `percentile` (0-100)")
        if self.metric == "hysteresis_width" and self.angle_deg is None:
            raise ValueError("metric hysteresis_width needs `angle_deg`")
        if r in ("increasing", "decreasing", "no_trend") and len(self.configurations) < 2:
            raise ValueError(f"relation {r} needs two or more configurations, in the stated order")
        if r in ("greater", "less", "equal"):
            if (self.than is None) == (self.value is None):
                raise ValueError(f"relation {r} needs exactly one of `than` (configurations) or `value`")
            if self.than is not None and len(self.than) != len(self.configurations):
                raise ValueError("`than` must list as many configurations as `configurations` (pairwise)")
        if self.baseline is not None:
            if r not in ("greater", "less", "equal", "inside"):
                raise ValueError(f"relation {r} takes no `baseline` (greater, less, equal and inside do)")
            if len(self.baseline) != len(self.configurations):
                raise ValueError("`baseline` must list as many configurations as `configurations` (pairwise)")
        if self.than_baseline is not None:
            if self.than is None:
                raise ValueError("`than_baseline` needs `than`")
            if len(self.than_baseline) != len(self.than):
                raise ValueError("`than_baseline` must list as many configurations as `than` (pairwise)")
        if r in ("equal", "no_trend") and self.margin is None:
            raise ValueError(
                f"relation {r} needs `margin` (in the metric's unit): the largest difference that still "
                "counts as equal, decided by an equivalence test"
            )
        if r not in ("equal", "no_trend") and self.margin is not None:
            raise ValueError(f"relation {r} takes no `margin` (equal and no_trend do)")
        if r == "inside":
            if self.interval is None:
                raise ValueError("relation inside needs `interval: [low, high]`")
            if not self.interval[0] < self.interval[1]:
                raise ValueError("`interval` must be [low, high] with low < high")
        return self


def statements(spec: ExpectationSpec) -> list[tuple[Terms, str]]:
    """The parts `spec` states, each as the weighted configurations whose combined mean is tested and its
    name ("3 minus 1"): each adjacent step of an increasing/decreasing order, each pair of a no_trend order,
    else each configuration (minus its `baseline`, minus its `than`, minus that one's `than_baseline`)."""
    r = spec.relation
    if r in ("increasing", "decreasing", "no_trend"):
        order = list(dict.fromkeys(spec.configurations))
        pairs = pairwise(order) if r != "no_trend" else combinations(order, 2)
        return [([(-1.0, a), (1.0, b)], f"{b} minus {a}") for a, b in pairs]
    out: list[tuple[Terms, str]] = []
    for i, key in enumerate(spec.configurations):
        terms: Terms = [(1.0, key)]
        name = str(key)
        if spec.baseline is not None:
            terms.append((-1.0, spec.baseline[i]))
            name += f" minus {spec.baseline[i]}"
        if spec.than is not None:
            terms.append((-1.0, spec.than[i]))
            other = str(spec.than[i])
            if spec.than_baseline is not None:
                terms.append((1.0, spec.than_baseline[i]))
                other = f"({other} minus {spec.than_baseline[i]})"
            name = f"({name}) minus {other}" if len(terms) > 2 else f"{name} minus {other}"
        out.append((terms, name))
    return out


def check_expectations(
    specs: Sequence[ExpectationSpec], keys: set[int], joints: Sequence[str] = (), *, several: bool = False
) -> Iterator[tuple[tuple[str | int, ...], str]]:
    """(location, message) for duplicate ids, configuration keys the matrix does not have, a `joint` that is
    not driven (`joints`: the driven joints, channel order) and, in a campaign driving several joints
    (`several`), an expectation that names neither `joint` nor `joints: all`."""
    seen: set[str] = set()
    shown = ", ".join(joints)
    for i, spec in enumerate(specs):
        if spec.id in seen:
            yield ("expectations", i, "id"), f"expectation id {spec.id!r} is used twice"
        seen.add(spec.id)
        if joints and spec.joint is not None and spec.joint not in joints:
            close = difflib.get_close_matches(spec.joint, list(joints), n=1, cutoff=0.75)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            yield (
                ("expectations", i, "joint"),
                f"{spec.joint!r} is not one of the driven joints ({shown}){hint}",
            )
        if several and spec.joint is None and spec.joints is None:
            yield (
                ("expectations", i),
                f"this campaign drives {len(joints)} joints ({shown}): say which joint's data decide "
                f"expectation {spec.id!r}, `joint: <one of them>`, or `joints: all` to decide it for each joint",
            )
        for field in ("configurations", "than", "baseline", "than_baseline"):
            for j, key in enumerate(getattr(spec, field) or ()):
                if key not in keys:
                    yield (
                        ("expectations", i, field, j),
                        f"no configuration has key {key} (keys: {key_spans(keys)})",
                    )


class RepeatabilitySpec(BaseModel):
    """A group of configurations with identical settings run in different sets (`report.repeatability`):
    the report gives their between-set CV and intraclass correlation, the trial as the unit."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=31)]
    text: str = ""
    configurations: list[StrictInt] = Field(min_length=2)


def check_repeatability(
    groups: Sequence[RepeatabilitySpec], settings: Mapping[int, Mapping[str, str]]
) -> Iterator[tuple[tuple[str | int, ...], str]]:
    """(location, message) for repeated names, unknown or repeated keys, and a configuration whose
    settings (`settings[key]`: trajectory and every factor's level) differ from the group's first."""
    names: set[str] = set()
    for i, group in enumerate(groups):
        where = ("report", "repeatability", i)
        if group.name in names:
            yield (*where, "name"), f"repeatability group name {group.name!r} is used twice"
        names.add(group.name)
        first: int | None = None
        seen: set[int] = set()
        for j, key in enumerate(group.configurations):
            loc = (*where, "configurations", j)
            if key not in settings:
                yield loc, f"no configuration has key {key}"
                continue
            if key in seen:
                yield loc, f"configuration {key} is listed twice"
                continue
            seen.add(key)
            if first is None:
                first = key
                continue
            ref, own = settings[first], settings[key]
            differ = [n for n in (*ref, *(n for n in own if n not in ref)) if ref.get(n) != own.get(n)]
            if differ:
                shown = "; ".join(f"{n} {own.get(n, '(unset)')} vs {ref.get(n, '(unset)')}" for n in differ)
                yield (
                    loc,
                    (
                        f"configuration {key} does not have the settings of configuration {first} ({shown}): "
                        "a repeatability group needs identical configurations"
                    ),
                )
