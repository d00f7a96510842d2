"""Resolving a configuration's level names (Appendix A) into physical settings.

A level may be an alias (`same_as`) of another level of the same family, e.g. friction `EMU` = level 2
and stiffness `K-EMU` = `K2`. Resolution assumes a validated protocol (see `protocol/validate.py`).
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import BaseModel

from .schema import ConfigurationSpec, Levels


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


def resolve_level(family: dict[str, BaseModel], name: str) -> BaseModel:
    """Follow `same_as` links to the level that carries the values (cycles are rejected by validation)."""
    level = family[name]
    seen = {name}
    while getattr(level, "same_as", None) is not None:
        target: str = level.same_as  # type: ignore[attr-defined]
        if target in seen or target not in family:
            raise KeyError(target)
        seen.add(target)
        level = family[target]
    return level


def resolve_settings(levels: Levels, cfg: ConfigurationSpec) -> Settings:
    brace = resolve_level(levels.brace_rom, cfg.brace_rom)  # type: ignore[arg-type]
    robot = resolve_level(levels.robot_rom, cfg.robot_rom)  # type: ignore[arg-type]
    friction = resolve_level(levels.friction, cfg.friction)  # type: ignore[arg-type]
    stiffness = resolve_level(levels.stiffness, cfg.stiffness)  # type: ignore[arg-type]
    preload = resolve_level(levels.preload, cfg.preload)  # type: ignore[arg-type]
    speed = resolve_level(levels.speed, cfg.speed)  # type: ignore[arg-type]
    return Settings(
        brace_rom=cfg.brace_rom,
        brace_rom_deg=tuple(brace.range_deg),  # type: ignore[attr-defined,arg-type]
        robot_rom=cfg.robot_rom,
        robot_rom_deg=tuple(robot.range_deg),  # type: ignore[attr-defined,arg-type]
        friction_level=cfg.friction,
        friction_nm=float(friction.torque_nm),  # type: ignore[attr-defined]
        friction_screw_turns=float(friction.screw_turns or 0.0),  # type: ignore[attr-defined]
        stiffness=cfg.stiffness,
        stiffness_n_per_mm=float(stiffness.n_per_mm),  # type: ignore[attr-defined]
        preload=cfg.preload,
        preload_position=int(preload.position),  # type: ignore[attr-defined]
        speed=cfg.speed,
        speed_deg_s=float(speed.max_deg_s),  # type: ignore[attr-defined]
    )
