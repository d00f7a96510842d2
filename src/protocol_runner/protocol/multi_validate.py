"""Plan-time checks of a multi-joint protocol's motions (`joints: [...]`), joint by joint.

Every configuration's motion is built for every driven joint (`resolve.configuration_trajectories`: a
`per_joint` entry or a file's column per joint, all lasting the same ticks); the park angle of each joint
must lie inside the stops of the elements that joint carries; then each joint's motions (its calibration
step and its part of every configuration) are checked field by field against ITS range, rate and
acceleration (`validate._limit_problems`) and as complete commanded streams (`stream_check.check_streams`,
approach from its park angle, exit, a stop after any sample) — the same checks a single-joint protocol
gets, run once per joint on that joint's view of the protocol. Messages name the configuration and the
joint.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InvalidInput
from ..models.element_types import ELEMENT_TYPES
from .resolve import BindingError, calibration_trajectory, configuration_trajectories, resolve_settings
from .trajectory_record import Trajectory

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc

Problem = tuple["Loc", str]
Motion = tuple["Loc", str, Trajectory]


def joint_view(loaded: LoadedProtocol, joint: str) -> LoadedProtocol:
    """The protocol as seen by one driven joint: `protocol.rig` is that joint's resolved rig."""
    p = loaded.protocol
    return dataclasses.replace(loaded, protocol=p.with_rigs((p.rig_of(joint),)))


def check_joint_motions(
    loaded: LoadedProtocol,
    *,
    check_files: bool,
    limit_problems: Callable[[LoadedProtocol, list[Motion], str], list[Problem]],
    relative_message: Callable[[str, Path], str],
) -> list[Problem]:
    """`limit_problems` and `relative_message` are validate.py's (passed in: no import cycle)."""
    from .stream_check import check_streams

    p = loaded.protocol
    problems: list[Problem] = []
    motions: dict[str, list[Motion]] = {
        j: [(("calibration_step",), f"the calibration step of joint {j}", calibration_trajectory(p, j))]
        for j in p.driven_joints
    }
    for i, s in enumerate(p.sets):
        for k, cfg in enumerate(s.configurations):
            loc: Loc = ("sets", i, "configurations", k)
            try:
                st = resolve_settings(p, cfg)
            except BindingError as exc:
                problems.append((exc.loc, exc.message))
                continue
            for joint in p.driven_joints:
                park = p.rig_of(joint).safety.park_angle_deg
                for el in st.device_of(joint):
                    rng = dict(el.params).get("range_deg")
                    stop = ELEMENT_TYPES[el.type].kind == "stop" and isinstance(rng, tuple)
                    if stop and isinstance(rng, tuple) and not rng[0] <= park <= rng[1]:
                        problems.append(
                            (
                                loc,
                                f"configuration {cfg.key}: joint {joint}'s park angle {park:g} deg is "
                                f"outside the stops [{rng[0]:g}, {rng[-1]:g}] deg of its element "
                                f"{el.name!r} (choose rig_overrides.joints.{joint}.safety.park_angle_deg "
                                "inside every stop range)",
                            )
                        )
            if p.profile_of(cfg) == "file" and not check_files:
                continue
            try:
                per_joint = configuration_trajectories(loaded, cfg, st)
            except BindingError as exc:
                problems.append((exc.loc, exc.message))
                continue
            except InvalidInput as exc:
                message = relative_message(exc.message, loaded.base_dir)
                problems.append(((*loc, "trajectory"), f"configuration {cfg.key}: {message}"))
                continue
            for joint, traj in per_joint:
                motions[joint].append((loc, f"configuration {cfg.key}, joint {joint}", traj))
    if problems:
        return problems
    for joint in p.driven_joints:
        problems += limit_problems(joint_view(loaded, joint), motions[joint], joint)
    if problems:
        return problems
    for joint in p.driven_joints:
        problems += list(check_streams(joint_view(loaded, joint), motions[joint], check_files=check_files))
    return problems
