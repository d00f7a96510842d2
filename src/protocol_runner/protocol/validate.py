"""Cross-field checks of a protocol that the schema alone cannot express (docs/protocol.md "What is
checked"); each returns (location, message) pairs so the loader can name the file line of the field.

A campaign of one joint (`joint:`) is a campaign whose only driven joint is that joint: the motion checks
iterate over the driven joints, each on its own view of the protocol (its rig, range and safety limits),
and name the joint in their messages only when the protocol names `joints:`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InvalidInput
from ..models.element_types import ELEMENT_TYPES
from .expectations import check_expectations, check_repeatability
from .only import key_spans
from .paths import OutsideFolder, confined_path
from .resolve import (
    BindingError,
    calibration_trajectory,
    check_bindings,
    configuration_motion,
    joints_named,
    resolve_settings,
)
from .schema import CalibrationStepSpec, ConfigurationSpec, Protocol
from .settings import ElementSetting
from .stream_check import check_streams, safety_limits, trajectory_limit_problems
from .trajectory_record import Trajectory
from .trajectory_specs import FileSpec, PerJointSpec, build_trajectory, joint_spec, trajectory_bindings

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc, Problem

Motion = tuple["Loc", str, Trajectory]

TRAJECTORY_PARAMETER = "trajectory"
"""A comparison's `parameter` that is not a factor: the configurations differ by their trajectory."""


def cross_check(
    loaded: LoadedProtocol, *, check_files: bool = True, generated: dict[Loc, Loc] | None = None
) -> list[Problem]:
    """Every problem as (location, message). `generated` maps a generated row's location to its
    generator's: a generated row is not in the file, so its problems are located at the generator."""
    generated = generated or {}
    p = loaded.protocol
    keys = {c.key for _, c in p.configurations()}
    settings = {c.key: {"trajectory": c.trajectory, **c.levels} for _, c in p.configurations()}
    problems = [
        *_check_factors(p),
        *_check_matrix(p),
        *check_bindings(p),
        *_check_calibration_step(p),
        *(_check_files(p, loaded.base_dir) if check_files else ()),
        *_check_unused_trajectories(loaded, check_files),
        *_check_report(p),
        *check_expectations(p.expectations, keys, p.driven_joints, several=len(p.driven_joints) > 1),
        *check_repeatability(p.report.repeatability, settings),
        *_check_output_budget(p),
    ]
    problems = problems or _check_motions(loaded, check_files, generated)
    return [(generated.get(loc[:4], loc), message) for loc, message in problems]


def _check_motions(loaded: LoadedProtocol, check_files: bool, generated: dict[Loc, Loc]) -> list[Problem]:
    """Every configuration resolved and its motion built for each driven joint; then each joint's motions
    (its calibration step and its part of every configuration) checked field by field against ITS range,
    rate and acceleration, and as complete commanded streams (approach from its park angle, exit, a stop
    after any sample), on that joint's view of the protocol. A configuration's problems that share a
    location and message are one line naming the configurations."""
    p = loaded.protocol
    per_joint = not isinstance(p.calibration_step, CalibrationStepSpec)
    motions: dict[str, list[Motion]] = {}
    for j in p.driven_joints:
        what = f"the calibration step of joint {j}" if p.multi_joint else "the calibration step"
        motions[j] = [
            (("calibration_step", *((j,) if per_joint else ())), what, calibration_trajectory(p, j))
        ]
    per_configuration: dict[tuple[Loc, str], list[tuple[str, int]]] = {}
    for i, s in enumerate(p.sets):
        for row, cfg in enumerate(s.configurations):
            loc: Loc = ("sets", i, "configurations", row)
            found, built = _configuration_motion(loaded, cfg, loc, check_files)
            for where, message in found:
                where = generated.get(where[:4], where)
                per_configuration.setdefault((where, message), []).append((s.name, cfg.key))
            for joint, traj in built:
                what = f"configuration {cfg.key}" + (f", joint {joint}" if p.multi_joint else "")
                motions[joint].append((loc, what, traj))
    all_keys = {c.key for _, c in p.configurations()}
    problems = [
        (loc, f"{message} ({_which_configurations(where, all_keys)})")
        for (loc, message), where in per_configuration.items()
    ]
    if problems:
        return problems
    for joint in p.driven_joints:  # each trajectory field against the joint's range, rate and acceleration
        problems += _limit_problems(
            _joint_view(loaded, joint), motions[joint], joint if p.multi_joint else ""
        )
    if problems:
        return problems
    for joint in p.driven_joints:  # every motion's complete commanded stream, approach and exit included
        problems += check_streams(_joint_view(loaded, joint), motions[joint], check_files=check_files)
    return problems


def _joint_view(loaded: LoadedProtocol, joint: str) -> LoadedProtocol:
    """The protocol as seen by one driven joint: `protocol.rig` is that joint's resolved rig."""
    p = loaded.protocol
    if len(p.rigs) == 1:
        return loaded
    return dataclasses.replace(loaded, protocol=p.with_rigs((p.rig_of(joint),)))


def output_budget(n_joints: int, report_time_s: float, rate_hz: float) -> tuple[float, float, int]:
    """(time the tick's output reports take, one tick, the largest whole rate in Hz whose tick holds
    them). The USB-3105 has no multi-channel report: a tick of N joints is N AOUT reports and one
    AOUT_SYNC (docs/hardware.md), each `report_time_s` on the wire."""
    needed_s = (n_joints + 1) * report_time_s
    return needed_s, 1.0 / rate_hz, math.floor(1.0 / needed_s + 1e-9)


def _check_output_budget(p: Protocol) -> Iterator[Problem]:
    """The output reports of one tick fit in that tick (1 / output rate)."""
    out = p.rig.output
    if out.report_time_s is None:
        return
    n = len(p.driven_joints)
    needed_s, tick_s, largest_hz = output_budget(n, out.report_time_s, out.rate_hz)
    if needed_s <= tick_s + 1e-12:
        return
    lowered = p.rig_overrides.output_rate_hz is not None
    where: Loc = (
        ("rig_overrides", "output_rate_hz") if lowered else ("joints",) if p.multi_joint else ("joint",)
    )
    joints = f"{n} joints need" if n > 1 else "1 joint needs"
    yield (
        where,
        f"{joints} {n + 1} output reports per tick ({n} AOUT + 1 AOUT_SYNC) of "
        f"{out.report_time_s * 1e3:g} ms each (report_time_s, {p.rig.rig_file}) = {needed_s * 1e3:g} ms, "
        f"more than one {tick_s * 1e3:g} ms tick at {out.rate_hz:g} Hz; the largest output rate that fits "
        f"is {largest_hz} Hz: set rig_overrides.output_rate_hz to {largest_hz} or less",
    )


def _which_configurations(where: list[tuple[str, int]], all_keys: set[int]) -> str:
    """ "configuration 4 in set 'speed'", "configurations 1-6 in set 'factorial'", "every configuration"
    (the sets are named when there are at most three)."""
    keys = sorted({k for _, k in where})
    if len(keys) > 1 and set(keys) == all_keys:
        return "every configuration"
    sets = list(dict.fromkeys(s for s, _ in where))
    noun = "configuration" if len(keys) == 1 else "configurations"
    if len(sets) > 3:
        return f"{noun} {key_spans(keys)}"
    in_sets = ("set " if len(sets) == 1 else "sets ") + ", ".join(repr(s) for s in sets)
    return f"{noun} {key_spans(keys)} in {in_sets}"


def _limit_problems(loaded: LoadedProtocol, motions: list[Motion], joint: str = "") -> list[Problem]:
    """The field of the trajectory (or of the calibration step) that breaks a limit, once per message
    (`joint`: of a multi-joint protocol, whose `loaded` is that joint's view)."""
    p = loaded.protocol
    limits = safety_limits(p.rig)
    out: dict[tuple[Loc, str], list[tuple[str, int]]] = {}
    for where, _, traj in motions:
        calibration = where[0] == "calibration_step"
        base, bindings = where, {}
        if not calibration:
            spec, prefix = joint_spec(p.trajectories[str(traj.name)], joint)
            base, bindings = ("trajectories", str(traj.name), *prefix), trajectory_bindings(spec)
        for field, message in trajectory_limit_problems(
            traj, limits, p.rig.output.rate_hz, loaded.base_dir, bindings
        ):
            which = ("", 0) if calibration else _set_and_key(p, where)
            out.setdefault(((*base, field), message), []).append(which)
    all_keys = {c.key for _, c in p.configurations()}
    of_joint = f", joint {joint}" if joint else ""
    return [
        (
            loc,
            f"{message}{f' (joint {joint})' if joint else ''}"
            if loc[0] == "calibration_step"
            else f"{message} ({_which_configurations(w, all_keys)}{of_joint})",
        )
        for (loc, message), w in out.items()
    ]


def _set_and_key(p: Protocol, loc: Loc) -> tuple[str, int]:
    """The set name and key of the row at ("sets", i, "configurations", j)."""
    i, j = int(loc[1]), int(loc[3])
    return p.sets[i].name, p.sets[i].configurations[j].key


def _within(rng: tuple[float, ...], joint: tuple[float, float]) -> bool:
    return joint[0] - 1e-9 <= rng[0] and rng[-1] <= joint[1] + 1e-9


def _fmt_range(rng: tuple[float, ...]) -> str:
    return f"[{rng[0]:g}, {rng[-1]:g}] deg"


def _check_factors(p: Protocol) -> Iterator[Problem]:
    # a multi-joint protocol's range quantities: inside some driven joint's range (each trajectory and
    # stop is then checked against its own joint's)
    lows, highs = zip(*(r.joint.range_deg for r in p.rigs), strict=True)
    joint = (min(lows), max(highs))
    for factor, levels in p.factors.items():
        if factor in (TRAJECTORY_PARAMETER,):
            yield ("factors", factor), f"{factor!r} is reserved (a comparison's parameter); rename the factor"
        for name, level in levels.items():
            loc: Loc = ("factors", factor, name)
            if level.same_as is not None:
                if level.quantities:
                    yield (
                        (*loc, level.quantities[0][0]),
                        "a level is either an alias (`same_as`) or has quantities, not both",
                    )
                target = levels.get(level.same_as)
                if target is None:
                    yield (*loc, "same_as"), f"unknown level {level.same_as!r} (known: {', '.join(levels)})"
                elif target.same_as is not None:
                    yield (
                        (*loc, "same_as"),
                        f"{level.same_as!r} is itself an alias; point at the level that has the values",
                    )
                continue
            for q, value in level.quantities:
                if q.endswith("range_deg") and isinstance(value, tuple) and not _within(value, joint):
                    yield (
                        (*loc, q),
                        f"{_fmt_range(value)} is outside the joint's range {_fmt_range(joint)} "
                        f"({', '.join(p.driven_joints)}, {p.rig.rig_file})",
                    )


def _check_matrix(p: Protocol) -> Iterator[Problem]:
    seen_sets: dict[str, int] = {}
    seen: dict[tuple[str, int], tuple[int, int]] = {}  # (field, value) -> its first (set, configuration)
    for i, s in enumerate(p.sets):
        if s.name in seen_sets:
            yield ("sets", i, "name"), f"set name {s.name!r} is already used by sets[{seen_sets[s.name]}]"
        seen_sets.setdefault(s.name, i)
        for j, cfg in enumerate(s.configurations):
            loc: Loc = ("sets", i, "configurations", j)
            for field, what, value in (("key", "key", cfg.key), ("run", "test run", cfg.run)):
                if (field, value) in seen:
                    a, b = seen[field, value]
                    yield (*loc, field), f"{what} {value} is already used by sets[{a}].configurations[{b}]"
                seen.setdefault((field, value), (i, j))
            for factor, label in cfg.levels.items():
                levels = p.factors.get(factor)
                if levels is None:
                    declared = ", ".join(p.factors) or "none"
                    yield (*loc, factor), f"unknown factor {factor!r} (declared factors: {declared})"
                elif label not in levels:
                    yield (*loc, factor), f"unknown level {label!r} (known: {', '.join(levels)})"
            if cfg.trajectory not in p.trajectories:
                known = ", ".join(p.trajectories)
                yield (*loc, "trajectory"), f"unknown trajectory {cfg.trajectory!r} (known: {known})"


def _configuration_motion(
    loaded: LoadedProtocol, cfg: ConfigurationSpec, loc: Loc, check_files: bool
) -> tuple[list[Problem], tuple[tuple[str, Trajectory], ...]]:
    """A configuration's problems (its bindings, a park angle against a stop it carries, its motion), and
    its motion per driven joint when that could be built."""
    p = loaded.protocol
    try:
        st = resolve_settings(p, cfg)
    except BindingError as exc:
        return [(exc.loc, exc.message)], ()
    found = [
        (loc, m) for joint in p.driven_joints for m in _park_against_stops(p, joint, st.device_of(joint))
    ]
    if p.profile_of(cfg) == "file" and not check_files:
        return found, ()
    try:
        return found, configuration_motion(loaded, cfg, st)
    except BindingError as exc:
        return [*found, (exc.loc, exc.message)], ()
    except InvalidInput as exc:
        return [*found, ((*loc, "trajectory"), _relative_message(exc.message, loaded.base_dir))], ()


def _park_against_stops(p: Protocol, joint: str, elements: tuple[ElementSetting, ...]) -> Iterator[str]:
    """Between trials a joint rests at its park angle: never against a stop of an element it carries."""
    park = p.rig_of(joint).safety.park_angle_deg
    for el in elements:
        rng = dict(el.params).get("range_deg")
        if ELEMENT_TYPES[el.type].kind != "stop" or not isinstance(rng, tuple) or rng[0] <= park <= rng[1]:
            continue
        whose, its, joints = (
            (f"joint {joint}'s", "its ", f"joints.{joint}.") if p.multi_joint else ("the", "", "..")
        )
        yield (
            f"{whose} park angle {park:g} deg is outside the stops {_fmt_range(rng)} of {its}element "
            f"{el.name!r}: between trials the joint would rest against a stop (choose "
            f"rig_overrides.{joints}safety.park_angle_deg inside every stop range)"
        )


def _check_calibration_step(p: Protocol) -> Iterator[Problem]:
    per_joint = not isinstance(p.calibration_step, CalibrationStepSpec)
    if per_joint and not p.multi_joint:
        yield ("calibration_step",), "a step per joint needs `joints:`; give from_deg, step_deg, ... here"
        return
    if per_joint:
        assert isinstance(p.calibration_step, dict)
        missing = list(
            joints_named(("calibration_step",), p.calibration_step, p.driven_joints, "calibration step")
        )
        yield from missing
        if missing:
            return
    for name in p.driven_joints:  # its range, rate and acceleration: checked with the motions
        step = p.calibration_step_of(name)
        if abs(step.step_deg) < p.calibration_check.min_step_deg:
            yield (
                ("calibration_step", *((name,) if per_joint else ()), "step_deg"),
                f"a {step.step_deg:g} deg step is smaller than calibration_check.min_step_deg = "
                f"{p.calibration_check.min_step_deg:g} deg: its response would be noise, not a time constant",
            )


def _check_files(p: Protocol, base: Path) -> Iterator[Problem]:
    """Referenced tables and datasets: confined to the protocol's folder (protocol/paths.py), then loaded.
    (Trajectory files are read when their trajectory is built.)"""
    from ..analysis.reference import load_reference_dataset
    from ..hardware.calibration import load_calibration_table

    for rig in p.rigs:
        for field in ("command_table", "angle_table", "torque_table"):
            rel = getattr(rig.calibration, field)
            if rel is not None:
                loc: Loc = ("rig_overrides", "joints", rig.joint.name, "calibration", field)
                yield from _check_loadable(loc, base, rel, "calibration table", load_calibration_table)
    ref = p.report.reference_dataset
    if ref is not None:
        loc = ("report", "reference_dataset")
        yield from _check_loadable(loc, base, ref, "reference dataset", load_reference_dataset)


def unused_trajectories(p: Protocol) -> list[str]:
    """The declared trajectories that no configuration uses, in declaration order."""
    used = {c.trajectory for _, c in p.configurations()}
    return [name for name in p.trajectories if name not in used]


def _check_unused_trajectories(loaded: LoadedProtocol, check_files: bool) -> Iterator[Problem]:
    """A trajectory that no configuration uses (docs/protocol.md "What is checked"): each of its entries
    whose fields are all constants is built for every driven joint as a configuration would build it and
    checked field by field, located at the entry (a file's build problems at its `file`). An entry with a
    bound field needs a configuration's levels: its bindings are checked with every other."""
    p = loaded.protocol
    found: dict[Problem, list[str]] = {}  # -> the joints it was built for ("" for a per_joint entry)
    for name in unused_trajectories(p):
        spec = p.trajectories[name]
        for joint in p.driven_joints:
            if isinstance(spec, PerJointSpec) and joint not in spec.joints:
                continue  # refused at its `joints` (check_bindings)
            entry, prefix = joint_spec(spec, joint)
            is_file = isinstance(entry, FileSpec)
            if trajectory_bindings(entry) or (is_file and not check_files):
                continue
            where: Loc = ("trajectories", name, *prefix)
            limits = safety_limits(p.rig_of(joint))
            try:
                built = build_trajectory(name, entry, {}, loaded.base_dir, joint=joint, limits=limits)
            except InvalidInput as exc:
                problems = [(("file",) if is_file else (), _relative_message(exc.message, loaded.base_dir))]
            else:
                rate_hz = p.rig.output.rate_hz
                problems = [
                    ((field,), message)
                    for field, message in trajectory_limit_problems(built, limits, rate_hz, loaded.base_dir)
                ]
            for field, message in problems:
                found.setdefault(((*where, *field), message), []).append("" if prefix else joint)
    for (loc, message), joints in found.items():
        # a multi-joint protocol's shared entry that fails for some joints only: name them
        some = [j for j in joints if j]
        of_joints = p.multi_joint and some and len(some) < len(p.driven_joints)
        yield loc, (f"joint {', '.join(some)}: {message}" if of_joints else message)


def _check_loadable(
    loc: Loc, base: Path, rel: str, what: str, load: Callable[[Path], object]
) -> Iterator[Problem]:
    try:
        path = confined_path(base, rel)
    except OutsideFolder as exc:
        yield loc, str(exc)
        return
    if not path.is_file():
        there = os.path.lexists(path)  # a FIFO, a device, a directory or a dangling link: not "not found"
        found = f"is not a regular file ({path})" if there else f"not found (looked in {path.parent})"
        yield loc, f"{what} {rel} {found}"
        return
    try:
        load(path)
    except InvalidInput as exc:
        yield loc, _relative_message(exc.message, base)


def _relative_message(message: str, base: Path) -> str:
    return message.replace(str(base) + "/", "")


def _check_report(p: Protocol) -> Iterator[Problem]:
    keys = {c.key for _, c in p.configurations()}
    names: set[str] = set()
    for i, comp in enumerate(p.report.comparisons):
        if comp.name in names:
            yield ("report", "comparisons", i, "name"), f"comparison name {comp.name!r} is used twice"
        names.add(comp.name)
        if comp.parameter != TRAJECTORY_PARAMETER and comp.parameter not in p.factors:
            yield (
                ("report", "comparisons", i, "parameter"),
                f"unknown parameter {comp.parameter!r}: a declared factor ({', '.join(p.factors)}) "
                f"or {TRAJECTORY_PARAMETER!r}",
            )
        for j, key in enumerate(comp.configurations):
            if key not in keys:
                yield (
                    ("report", "comparisons", i, "configurations", j),
                    f"no configuration has key {key} (keys: {key_spans(keys)})",
                )
    for i, pred in enumerate(p.report.predictions):
        for field_name in ("fit", "predict"):
            if getattr(pred, field_name) not in keys:
                yield (
                    ("report", "predictions", i, field_name),
                    f"no configuration has key {getattr(pred, field_name)} (keys: {key_spans(keys)})",
                )
        if pred.fit == pred.predict:
            yield ("report", "predictions", i, "predict"), "a prediction needs two different configurations"
