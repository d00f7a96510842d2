"""Cross-field checks of a protocol that the schema alone cannot express.

Each check returns (location, message) pairs so the loader can name the file line of the offending field.
Checks: levels and their aliases; every referenced level and trajectory exists; ranges lie inside the
joint's range; trajectories respect the joint's range, speed and acceleration limits; keys, run numbers and
names are unique; referenced files lie in the protocol's folder, exist and load.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InvalidInput
from ..hardware.conversions import RSST_JOINTS
from .expectations import check_expectations
from .paths import OutsideFolder, confined_path
from .schema import LEVEL_FAMILIES, ConfigurationSpec, Protocol
from .trajectories import (
    calibration_step_peak_speed_deg_s,
    load_trajectory_file,
    max_speed_deg_s,
    sinusoid_period_s,
)

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc

Problem = tuple["Loc", str]

_LEVEL_VALUE_FIELD = {
    "brace_rom": "range_deg",
    "robot_rom": "range_deg",
    "friction": "torque_nm",
    "stiffness": "n_per_mm",
    "speed": "max_deg_s",
    "preload": "position",
}


def cross_check(loaded: LoadedProtocol, *, check_files: bool = True) -> list[Problem]:
    p = loaded.protocol
    problems: list[Problem] = []
    problems += list(_check_levels(p))
    problems += list(_check_rig(p))
    problems += list(_check_matrix(p))
    problems += list(_check_trajectories(p))
    if check_files:
        problems += list(_check_files(p, loaded.base_dir))
    problems += list(_check_report(p))
    problems += list(check_expectations(p.expectations, {c.key for _, c in p.configurations()}))
    if not problems:  # every motion's complete commanded stream, approach and exit included
        from .stream_check import check_streams

        problems += list(check_streams(loaded, check_files=check_files))
    return problems


def _within(rng: tuple[float, float], joint: tuple[float, float]) -> bool:
    return joint[0] - 1e-9 <= rng[0] and rng[1] <= joint[1] + 1e-9


def _fmt_range(rng: tuple[float, float]) -> str:
    return f"[{rng[0]:g}, {rng[1]:g}] deg"


def _check_levels(p: Protocol) -> Iterator[Problem]:
    joint = p.rig.joint.range_deg
    for family_name in LEVEL_FAMILIES:
        family: dict[str, Any] = getattr(p.levels, family_name)
        value_field = _LEVEL_VALUE_FIELD[family_name]
        for name, level in family.items():
            loc: Loc = ("levels", family_name, name)
            value = getattr(level, value_field)
            if level.same_as is not None:
                if value is not None:
                    yield (
                        (*loc, value_field),
                        f"a level is either an alias (`same_as`) or has `{value_field}`, not both",
                    )
                target = family.get(level.same_as)
                if target is None:
                    known = ", ".join(family)
                    yield (*loc, "same_as"), f"unknown level {level.same_as!r} (known: {known})"
                elif target.same_as is not None:
                    yield (
                        (*loc, "same_as"),
                        f"{level.same_as!r} is itself an alias; point at the level that has the values",
                    )
            elif value is None:
                yield loc, f"missing `{value_field}` (or `same_as: <another {family_name} level>`)"
            elif value_field == "range_deg":
                lo, hi = value
                if not lo < hi:
                    yield (
                        (*loc, "range_deg"),
                        f"range must be [low, high] with low < high, got [{lo:g}, {hi:g}]",
                    )
                elif not _within(value, joint):
                    yield (
                        (*loc, "range_deg"),
                        f"{_fmt_range(value)} is outside the joint's range {_fmt_range(joint)}",
                    )
                elif family_name == "brace_rom" and not lo <= p.rig.safety.park_angle_deg <= hi:
                    yield (
                        (*loc, "range_deg"),
                        f"the park angle rig.safety.park_angle_deg = {p.rig.safety.park_angle_deg:g} deg is outside "
                        f"this brace range {_fmt_range(value)}: between trials the joint would rest against the stop",
                    )


def _check_rig(p: Protocol) -> Iterator[Problem]:
    rig = p.rig
    joint = rig.joint.range_deg
    if rig.input.angle_channel == rig.input.torque_channel:
        yield ("rig", "input", "torque_channel"), "angle and torque cannot use the same input channel"
    if not joint[0] <= rig.safety.park_angle_deg <= joint[1]:
        yield (
            ("rig", "safety", "park_angle_deg"),
            (
                f"park angle {rig.safety.park_angle_deg:g} deg is outside the joint's range {_fmt_range(joint)}"
            ),
        )
    if rig.joint.rsst_joint is not None:
        spec = RSST_JOINTS.get(rig.joint.rsst_joint)
        if spec is not None:
            table_range = tuple(spec.range_deg)
            if not _within(joint, table_range):  # type: ignore[arg-type]
                yield (
                    ("rig", "joint", "range_deg"),
                    (
                        f"{_fmt_range(joint)} exceeds RSST joint {rig.joint.rsst_joint}'s range "
                        f"{_fmt_range(table_range)} (thesis Table 2)"  # type: ignore[arg-type]
                    ),
                )


def _level_ref_problem(p: Protocol, cfg: ConfigurationSpec, family: str) -> str | None:
    name = getattr(cfg, family)
    levels: dict[str, Any] = getattr(p.levels, family)
    if name in levels:
        return None
    return f"unknown level {name!r} (known: {', '.join(levels)})"


def _check_matrix(p: Protocol) -> Iterator[Problem]:
    seen_sets: dict[str, int] = {}
    seen_keys: dict[int, tuple[int, int]] = {}
    seen_runs: dict[int, tuple[int, int]] = {}
    for i, s in enumerate(p.sets):
        if s.name in seen_sets:
            yield ("sets", i, "name"), f"set name {s.name!r} is already used by sets[{seen_sets[s.name]}]"
        seen_sets.setdefault(s.name, i)
        for j, cfg in enumerate(s.configurations):
            loc: Loc = ("sets", i, "configurations", j)
            if cfg.key in seen_keys:
                a, b = seen_keys[cfg.key]
                yield (*loc, "key"), f"key {cfg.key} is already used by sets[{a}].configurations[{b}]"
            seen_keys.setdefault(cfg.key, (i, j))
            if cfg.run in seen_runs:
                a, b = seen_runs[cfg.run]
                yield (*loc, "run"), f"test run {cfg.run} is already used by sets[{a}].configurations[{b}]"
            seen_runs.setdefault(cfg.run, (i, j))
            for family in LEVEL_FAMILIES:
                msg = _level_ref_problem(p, cfg, family)
                if msg:
                    yield (*loc, family), msg
            yield from _check_configuration_trajectory(p, cfg, loc)


def _check_configuration_trajectory(p: Protocol, cfg: ConfigurationSpec, loc: Loc) -> Iterator[Problem]:
    limits = p.rig.safety
    if cfg.profile == "human":
        if cfg.trajectory is None:
            yield (
                (*loc, "trajectory"),
                "a human profile needs `trajectory: <name of a trajectories.human entry>`",
            )
        elif cfg.trajectory not in p.trajectories.human:
            known = ", ".join(p.trajectories.human) or "none defined"
            yield (*loc, "trajectory"), f"unknown trajectory {cfg.trajectory!r} (known: {known})"
        return
    if cfg.trajectory is not None:
        yield (*loc, "trajectory"), f"a {cfg.profile} profile is built from the protocol; remove `trajectory`"
    if cfg.profile == "identification":
        if p.trajectories.identification is None:
            yield (*loc, "profile"), "profile `identification` needs a `trajectories.identification` section"
        return
    # sinusoid: range from robot_rom, period from speed (Eq 24-25)
    robot = p.levels.robot_rom.get(cfg.robot_rom)
    speed = p.levels.speed.get(cfg.speed)
    if robot is None or speed is None:
        return  # reported as unknown levels
    robot_range = robot.range_deg or _alias_value(p.levels.robot_rom, robot.same_as, "range_deg")
    speed_deg_s = speed.max_deg_s or _alias_value(p.levels.speed, speed.same_as, "max_deg_s")
    if robot_range is None or speed_deg_s is None:
        return
    if speed_deg_s > limits.max_rate_deg_s:
        yield (
            (*loc, "speed"),
            (
                f"{speed_deg_s:g} deg/s exceeds the rig's rate limit rig.safety.max_rate_deg_s = {limits.max_rate_deg_s:g}"
            ),
        )
    amplitude = (robot_range[1] - robot_range[0]) / 2.0
    if amplitude > 0:
        period = sinusoid_period_s(amplitude, speed_deg_s)
        accel = amplitude * (2 * math.pi / period) ** 2
        if accel > limits.max_accel_deg_s2:
            yield (
                (*loc, "speed"),
                (
                    f"the sinusoid's peak acceleration {accel:.0f} deg/s^2 exceeds rig.safety.max_accel_deg_s2 = "
                    f"{limits.max_accel_deg_s2:g}"
                ),
            )


def _alias_value(family: dict[str, Any], target: str | None, field: str) -> Any:
    if target is None or target not in family:
        return None
    return getattr(family[target], field)


def _check_trajectories(p: Protocol) -> Iterator[Problem]:
    joint = p.rig.joint.range_deg
    step = p.trajectories.calibration_step
    for value, field in ((step.from_deg, "from_deg"), (step.from_deg + step.step_deg, "step_deg")):
        if not joint[0] <= value <= joint[1]:
            yield (
                ("trajectories", "calibration_step", field),
                (
                    f"the calibration step reaches {value:g} deg, outside the joint's range {_fmt_range(joint)}"
                ),
            )
    peak = calibration_step_peak_speed_deg_s(step.step_deg, step.ramp_s)
    if peak > p.rig.safety.max_rate_deg_s:
        yield (
            ("trajectories", "calibration_step", "ramp_s"),
            (
                f"a {abs(step.step_deg):g} deg step over {step.ramp_s:g} s peaks at {peak:.0f} deg/s, above "
                f"rig.safety.max_rate_deg_s = {p.rig.safety.max_rate_deg_s:g}; lengthen ramp_s"
            ),
        )
    ident = p.trajectories.identification
    if ident is not None and not _within(ident.range_deg, joint):
        yield (
            ("trajectories", "identification", "range_deg"),
            (f"{_fmt_range(ident.range_deg)} is outside the joint's range {_fmt_range(joint)}"),
        )


def _check_files(p: Protocol, base: Path) -> Iterator[Problem]:
    """Every referenced file: confined to the protocol's folder (protocol/paths.py), then loaded and checked."""
    joint = p.rig.joint.range_deg
    limits = p.rig.safety
    for name, spec in p.trajectories.human.items():
        loc: Loc = ("trajectories", "human", name, "file")
        try:
            traj = load_trajectory_file(confined_path(base, spec.file))
        except OutsideFolder as exc:
            yield loc, str(exc)
            continue
        except InvalidInput as exc:
            yield loc, _relative_message(exc.message, base)
            continue
        lo, hi = float(np.min(traj.angle_deg)), float(np.max(traj.angle_deg))
        if not _within((lo, hi), joint):
            yield (
                loc,
                f"{spec.file} goes to [{lo:.1f}, {hi:.1f}] deg, outside the joint's range {_fmt_range(joint)}",
            )
        speed = max_speed_deg_s(traj.time_s, traj.angle_deg)
        if speed > limits.max_rate_deg_s:
            yield (
                loc,
                f"{spec.file} moves at up to {speed:.0f} deg/s, above rig.safety.max_rate_deg_s = {limits.max_rate_deg_s:g}",
            )
    for field in ("command_table", "angle_table", "torque_table"):
        rel = getattr(p.rig.calibration, field)
        if rel is not None:
            yield from _check_loadable(("rig", "calibration", field), base, rel, "calibration table")
    ref = p.report.reference_dataset
    if ref is not None:
        yield from _check_loadable(("report", "reference_dataset"), base, ref, "reference dataset")


def _check_loadable(loc: Loc, base: Path, rel: str, what: str) -> Iterator[Problem]:
    try:
        path = confined_path(base, rel)
    except OutsideFolder as exc:
        yield loc, str(exc)
        return
    if not path.is_file():
        yield loc, f"{what} {rel} not found (looked in {path.parent})"
        return
    try:
        if what == "calibration table":
            from ..hardware.calibration import load_calibration_table

            load_calibration_table(path)
        else:
            from ..analysis.reference import load_reference_dataset

            load_reference_dataset(path)
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
        for j, key in enumerate(comp.configurations):
            if key not in keys:
                yield ("report", "comparisons", i, "configurations", j), f"no configuration has key {key}"
    for i, pred in enumerate(p.report.predictions):
        for field_name in ("fit", "predict"):
            if getattr(pred, field_name) not in keys:
                yield (
                    ("report", "predictions", i, field_name),
                    f"no configuration has key {getattr(pred, field_name)}",
                )
        if pred.fit == pred.predict:
            yield ("report", "predictions", i, "predict"), "a prediction needs two different configurations"
