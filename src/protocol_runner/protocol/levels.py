"""Resolving a configuration's level names (Appendix A) into physical settings.

A level may be an alias (`same_as`) of another level of the same family, e.g. friction `EMU` = level 2
and stiffness `K-EMU` = `K2`. Resolution assumes a validated protocol (see `protocol/validate.py`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from .schema import ConfigurationSpec, Levels, Protocol
from .settings import FactorSetting, Quantity
from .settings import Settings as FactorSettings
from .trajectories import load_trajectory_file

if TYPE_CHECKING:
    from .loaded import LoadedProtocol


@dataclass(frozen=True)
class Settings:
    """The physical settings of one configuration (the plan's `settings`)."""

    brace_rom: str
    brace_rom_deg: tuple[float, float]
    robot_rom: str
    robot_rom_deg: tuple[float, float]
    friction_level: str
    friction_nm: float
    friction_screw_turns: float
    stiffness: str
    stiffness_n_per_mm: float
    preload: str
    preload_position: int
    speed: str
    speed_deg_s: float

    def as_settings(self) -> FactorSettings:
        """Transitional: these settings as declared factors (the schema-2 shape of protocol/settings.py)."""

        def f(level: str, *q: tuple[str, Quantity]) -> FactorSetting:
            return FactorSetting(level=level, quantities=tuple(q))

        return FactorSettings(
            factors=(
                ("brace_rom", f(self.brace_rom, ("range_deg", self.brace_rom_deg))),
                ("robot_rom", f(self.robot_rom, ("range_deg", self.robot_rom_deg))),
                (
                    "friction",
                    f(
                        self.friction_level,
                        ("friction_nm", self.friction_nm),
                        ("screw_turns", self.friction_screw_turns),
                    ),
                ),
                ("stiffness", f(self.stiffness, ("stiffness_n_per_mm", self.stiffness_n_per_mm))),
                ("speed", f(self.speed, ("speed_deg_s", self.speed_deg_s))),
                ("preload", f(self.preload, ("position_index", float(self.preload_position)))),
            )
        )

    def to_json(self) -> dict[str, object]:
        """The plan contract's `settings` object (DESIGN.md), plus the level names and extras."""
        return {
            "brace_rom": self.brace_rom,
            "brace_rom_deg": list(self.brace_rom_deg),
            "robot_rom": self.robot_rom,
            "robot_rom_deg": list(self.robot_rom_deg),
            "friction_level": self.friction_level,
            "friction_nm": self.friction_nm,
            "friction_screw_turns": self.friction_screw_turns,
            "stiffness": self.stiffness,
            "stiffness_n_per_mm": self.stiffness_n_per_mm,
            "preload": self.preload,
            "preload_position": self.preload_position,
            "speed": self.speed,
            "speed_deg_s": self.speed_deg_s,
        }


L = TypeVar("L")


def resolve_level(family: Mapping[str, L], name: str) -> L:
    """Follow `same_as` links to the level that carries the values (cycles are rejected by validation)."""
    level = family[name]
    seen = {name}
    while (target := getattr(level, "same_as", None)) is not None:
        if target in seen or target not in family:
            raise KeyError(target)
        seen.add(target)
        level = family[target]
    return level


T = TypeVar("T")


def _present(value: T | None, what: str) -> T:
    if value is None:  # validation guarantees a value; this guards direct use of unvalidated data
        raise ValueError(f"level has no {what}")
    return value


def resolve_settings(levels: Levels, cfg: ConfigurationSpec) -> Settings:
    brace = _present(resolve_level(levels.brace_rom, cfg.brace_rom).range_deg, "range_deg")
    robot = _present(resolve_level(levels.robot_rom, cfg.robot_rom).range_deg, "range_deg")
    friction = resolve_level(levels.friction, cfg.friction)
    stiffness = resolve_level(levels.stiffness, cfg.stiffness)
    preload = resolve_level(levels.preload, cfg.preload)
    speed = resolve_level(levels.speed, cfg.speed)
    return Settings(
        brace_rom=cfg.brace_rom,
        brace_rom_deg=(float(brace[0]), float(brace[1])),
        robot_rom=cfg.robot_rom,
        robot_rom_deg=(float(robot[0]), float(robot[1])),
        friction_level=cfg.friction,
        friction_nm=float(_present(friction.torque_nm, "torque_nm")),
        friction_screw_turns=float(friction.screw_turns or 0.0),
        stiffness=cfg.stiffness,
        stiffness_n_per_mm=float(_present(stiffness.n_per_mm, "n_per_mm")),
        preload=cfg.preload,
        preload_position=int(_present(preload.position, "position")),
        speed=cfg.speed,
        speed_deg_s=float(_present(speed.max_deg_s, "max_deg_s")),
    )


def with_motion_range(
    p: Protocol, loaded: LoadedProtocol | None, cfg: ConfigurationSpec, settings: Settings
) -> Settings:
    """A human-profile configuration moves through its subject's motion file, not through a robot range
    level: record the motion's name and the angle range its file spans (Table 5's motion range)."""
    if cfg.profile != "human" or cfg.trajectory is None or loaded is None:
        return settings
    spec = p.trajectories.human[cfg.trajectory]
    angle = load_trajectory_file(loaded.base_dir / spec.file).angle_deg
    return replace(
        settings,
        robot_rom=f"{cfg.trajectory} (motion file)",
        robot_rom_deg=(float(np.min(angle)), float(np.max(angle))),
    )
