"""The findings of thesis Chapter 5, checked against an archive's numbers.

Each `Finding` states what the thesis found, where (section), the numbers measured in this session and
whether they agree (`None` when the archive lacks the configurations the comparison needs). Energy per
cycle is Eq 10-12 (thesis §5.7.1) as archived in `energy_loss_j`; angle ranges and torque-angle slopes
come from the processed brace-on data (`ReportData` summaries).

The configurations of each comparison come from the archive's `/comparisons/<name>` groups (the one whose
`parameter` matches and whose keys overlap the thesis's most); the thesis's keys (Appendix A, Table 5)
are the documented fallback.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from protocol_runner.report.model import Configuration, ReportData

#: Slack allowed on the angle statements of §5.2 (degrees): "about 110°", "about 25-105°".
ANGLE_TOLERANCE_DEG = 10.0


@dataclass(frozen=True)
class Finding:
    """One Chapter 5 statement and whether this session's data agrees (None: not enough data)."""

    title: str
    thesis_statement: str
    section: str
    agrees: bool | None
    numbers: str
    configurations: tuple[int, ...] = ()


# parameter aliases accepted in /comparisons/<name> attribute `parameter` (lower case)
_ALIASES: dict[str, tuple[str, ...]] = {
    "friction": ("friction", "friction_level", "friction_nm", "brake_friction"),
    "robot_rom": ("robot_rom", "robot_rom_deg", "rom", "range_of_motion", "trajectory_rom", "rom_trajectory"),
    "brace_rom": ("brace_rom", "brace_rom_deg", "rom_brace", "brace_range_of_motion"),
    "speed": ("speed", "speed_deg_s"),
    "preload": ("preload", "preload_position", "spring_preload"),
    "stiffness": ("stiffness", "stiffness_n_per_mm", "spring", "spring_stiffness"),
}

_FALLBACK: dict[str, tuple[int, ...]] = {
    "friction": (4, 5, 6, 7),
    "robot_rom": (12, 13, 14),
    "brace_rom": (1, 2, 3),
    "speed": (10, 11),
    "preload": (8, 3, 9),
    "stiffness": (17, 20, 14, 23),
}


def comparison_keys(data: ReportData, parameter: str) -> tuple[int, ...]:
    """Configuration keys compared for `parameter` (archive's `/comparisons` first, thesis's fallback)."""
    fallback = _FALLBACK[parameter]
    aliases = _ALIASES[parameter]
    best: tuple[int, ...] | None = None
    best_score = (-1, 0)
    for comp in data.comparisons:
        if not comp.from_archive:
            continue
        if comp.parameter.lower() not in aliases and comp.name.lower() not in aliases:
            continue
        keys = set(comp.configurations)
        # most keys in common with the thesis's, then fewest others (brace_rom [1, 2, 3] beats the
        # restraint comparison [1, 2, 3, 12, 13, 14] that shares its parameter)
        score = (len(keys & set(fallback)), -len(keys - set(fallback)))
        if score > best_score:
            best, best_score = comp.configurations, score
    return best if best is not None else fallback


def evaluate_findings(data: ReportData) -> tuple[Finding, ...]:
    """Every Chapter 5 finding checked against `data`, in the thesis's order."""
    return (
        _speed(data),
        _k2_upper_limit(data),
        _r1_actual_range(data),
        _stiffness_slope(data),
        _stiffness_range(data),
        _preload_slope(data),
        _energy_friction(data),
        _energy_rom(data),
        _energy_restraint(data),
        _energy_preload(data),
        _energy_springs(data),
    )


# ------------------------------------------------------------------------------------------- helpers


def _with_energy(data: ReportData, keys: Sequence[int]) -> list[Configuration]:
    out = []
    for key in keys:
        cfg = data.configuration(key)
        if cfg is not None and cfg.energy_loss_j.size > 0:
            out.append(cfg)
    return out


def _with_angles(data: ReportData, keys: Sequence[int]) -> list[Configuration]:
    out = []
    for key in keys:
        cfg = data.configuration(key)
        if cfg is not None and math.isfinite(cfg.angle_max_deg):
            out.append(cfg)
    return out


def _num(cfg: Configuration, name: str, default: float = math.nan) -> float:
    value = cfg.setting(name, default)
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return default


def _span(value: object) -> float:
    stop = _stop(value)
    return stop[1] - stop[0] if stop else math.nan


def _sorted_by(cfgs: list[Configuration], key: Callable[[Configuration], float]) -> list[Configuration]:
    # configurations whose parameter is unknown keep their comparison order, after the known ones
    return sorted(cfgs, key=lambda c: (math.isnan(key(c)), key(c) if not math.isnan(key(c)) else 0.0))


def _energy_text(cfg: Configuration, label: str) -> str:
    std = cfg.energy_std_j
    spread = f" ± {std:.2f}" if math.isfinite(std) else ""
    return f"config {cfg.key} ({label}): {cfg.energy_mean_j:.2f}{spread} J/cycle"


def _increasing(values: Sequence[float]) -> bool:
    return all(b > a for a, b in pairwise(values))


def _not_enough(title: str, statement: str, section: str, keys: Sequence[int], need: str) -> Finding:
    return Finding(title, statement, section, None, f"Not enough data: {need}.", tuple(keys))


def _sem(cfg: Configuration) -> float:
    n = cfg.energy_loss_j.size
    return cfg.energy_std_j / math.sqrt(n) if n > 1 and math.isfinite(cfg.energy_std_j) else 0.0


# ------------------------------------------------------------------------------------------ findings


def _energy_friction(data: ReportData) -> Finding:
    title = "Energy loss grows with friction"
    statement = "The energy loss increases with increasing friction of the brace (trials 4-7, Figure 43)."
    keys = comparison_keys(data, "friction")
    cfgs = _sorted_by(_with_energy(data, keys), lambda c: _num(c, "friction_nm"))
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.3, 5.7.2", keys, "two or more friction levels with energies")
    energies = [c.energy_mean_j for c in cfgs]
    text = "; ".join(_energy_text(c, f"friction {_num(c, 'friction_nm'):.2f} N·m") for c in cfgs)
    return Finding(title, statement, "5.3, 5.7.2", _increasing(energies), text, tuple(keys))


def _energy_rom(data: ReportData) -> Finding:
    title = "Energy loss grows with range of motion"
    statement = "The energy loss increases with the range of motion (trials 12-14, Figure 41)."
    keys = comparison_keys(data, "robot_rom")
    cfgs = _sorted_by(_with_energy(data, keys), lambda c: _span(c.setting("robot_rom_deg")))
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.7.2", keys, "two or more trajectory ranges with energies")
    text = "; ".join(_energy_text(c, f"ROM {_span(c.setting('robot_rom_deg')):.0f}°") for c in cfgs)
    return Finding(title, statement, "5.7.2", _increasing([c.energy_mean_j for c in cfgs]), text, tuple(keys))


def _energy_restraint(data: ReportData) -> Finding:
    title = "A restrained range loses more than a smaller trajectory"
    statement = (
        "The energy loss increases when the range of motion is physically limited, rather than inputting a "
        "smaller trajectory (trials 1-3 against 12-14, Figure 42)."
    )
    restrained = _with_energy(data, comparison_keys(data, "brace_rom"))
    trajectory = _with_energy(data, comparison_keys(data, "robot_rom"))
    keys = tuple(c.key for c in restrained) + tuple(c.key for c in trajectory)
    pairs: list[tuple[Configuration, Configuration]] = []
    for r in restrained:
        for t in trajectory:
            same_stop = _span(r.setting("brace_rom_deg")) == _span(t.setting("brace_rom_deg"))
            different_trajectory = _span(r.setting("robot_rom_deg")) != _span(t.setting("robot_rom_deg"))
            if same_stop and different_trajectory:
                pairs.append((r, t))
    if not pairs:
        return _not_enough(
            title, statement, "5.7.2", keys, "pairs with the same brace stop but different trajectories"
        )
    agrees = all(r.energy_mean_j > t.energy_mean_j for r, t in pairs)
    text = "; ".join(
        f"stop {_span(r.setting('brace_rom_deg')):.0f}°: restrained config {r.key} {r.energy_mean_j:.2f} J "
        f"vs trajectory config {t.key} {t.energy_mean_j:.2f} J"
        for r, t in pairs
    )
    return Finding(title, statement, "5.7.2", agrees, text, keys)


def _speed(data: ReportData) -> Finding:
    title = "Half speed loses at least as much energy as full speed"
    statement = (
        "The energy loss decreases with the speed of the trajectory (trials 10 and 11, Figure 44); the half "
        "speed loop encloses higher torques (§5.1)."
    )
    keys = comparison_keys(data, "speed")
    cfgs = _sorted_by(_with_energy(data, keys), lambda c: _num(c, "speed_deg_s"))
    if len(cfgs) < 2:
        return _not_enough(
            title, statement, "5.1, 5.7.2", keys, "a half-speed and a full-speed configuration"
        )
    slow, fast = cfgs[0], cfgs[-1]
    # "at least as much": equal within one combined standard error of the means still agrees
    tolerance = math.hypot(_sem(slow), _sem(fast))
    agrees = slow.energy_mean_j >= fast.energy_mean_j - tolerance
    slow_label = f"{_num(slow, 'speed_deg_s'):.0f} deg/s"
    fast_label = f"{_num(fast, 'speed_deg_s'):.0f} deg/s"
    text = f"{_energy_text(slow, slow_label)}; {_energy_text(fast, fast_label)}"
    return Finding(title, statement, "5.1, 5.7.2", agrees, text, tuple(keys))


def _preload_amount_order(cfg: Configuration) -> float:
    # Eq 17: the screw position n grows toward lower preloads, so the preload grows as -n.
    return -_num(cfg, "preload_position")


def _energy_preload(data: ReportData) -> Finding:
    title = "Greater preload loses less energy"
    statement = (
        "The energy loss decreases with greater preloads (trials 8, 9 and 3, Figure 45), probably because "
        "the robot reaches its torque limit at a smaller angle."
    )
    keys = comparison_keys(data, "preload")
    cfgs = _sorted_by(_with_energy(data, keys), _preload_amount_order)
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.7.2", keys, "two or more preload positions with energies")
    energies = [c.energy_mean_j for c in cfgs]
    agrees = all(b < a for a, b in pairwise(energies))
    text = (
        "; ".join(_energy_text(c, f"preload position {_num(c, 'preload_position'):.0f}") for c in cfgs)
        + " (ordered from the least to the greatest preload, Eq 17)"
    )
    return Finding(title, statement, "5.5, 5.7.2", agrees, text, tuple(keys))


def _preload_slope(data: ReportData) -> Finding:
    title = "Greater preload steepens the torque-angle slope"
    statement = "By increasing the preload, the slope of the torque vs. angle graph also increases (§5.5)."
    keys = comparison_keys(data, "preload")
    cfgs = [c for c in _with_angles(data, keys) if math.isfinite(c.torque_slope_nm_per_deg)]
    cfgs = _sorted_by(cfgs, _preload_amount_order)
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.5", keys, "two or more preload positions with processed data")
    slopes = [c.torque_slope_nm_per_deg for c in cfgs]
    text = "; ".join(
        f"config {c.key} (position {_num(c, 'preload_position'):.0f}): {c.torque_slope_nm_per_deg:.3f} N·m/deg"
        for c in cfgs
    )
    return Finding(title, statement, "5.5", _increasing(slopes), text, tuple(keys))


def _energy_springs(data: ReportData) -> Finding:
    title = "No clear relation between spring and energy loss"
    statement = (
        "There is no clear relationship between the different springs and the energy loss (Figure 46), "
        "though theory expects more loss with stiffer springs."
    )
    keys = comparison_keys(data, "stiffness")
    cfgs = _sorted_by(_with_energy(data, keys), lambda c: _num(c, "stiffness_n_per_mm"))
    if len(cfgs) < 3:
        return _not_enough(title, statement, "5.7.2", keys, "three or more springs with energies")

    def clear(sign: float) -> bool:
        # a clear relation: every step between successive springs goes the same way by more than the spread
        for a, b in pairwise(cfgs):
            spread = math.hypot(
                a.energy_std_j if math.isfinite(a.energy_std_j) else 0.0,
                b.energy_std_j if math.isfinite(b.energy_std_j) else 0.0,
            )
            if sign * (b.energy_mean_j - a.energy_mean_j) <= spread:
                return False
        return True

    agrees = not (clear(1.0) or clear(-1.0))
    text = "; ".join(_energy_text(c, f"{_num(c, 'stiffness_n_per_mm'):.1f} N/mm") for c in cfgs)
    return Finding(title, statement, "5.7.2", agrees, text, tuple(keys))


def _stiffness_slope(data: ReportData) -> Finding:
    title = "Stiffer springs steepen the torque-angle slope"
    statement = "Increasing the spring stiffness changed the slope of the torque vs. angle graph (§5.4)."
    keys = comparison_keys(data, "stiffness")
    cfgs = [c for c in _with_angles(data, keys) if math.isfinite(c.torque_slope_nm_per_deg)]
    cfgs = _sorted_by(cfgs, lambda c: _num(c, "stiffness_n_per_mm"))
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.4", keys, "two or more springs with processed data")
    text = "; ".join(
        f"config {c.key} ({_num(c, 'stiffness_n_per_mm'):.1f} N/mm): {c.torque_slope_nm_per_deg:.3f} N·m/deg"
        for c in cfgs
    )
    return Finding(
        title, statement, "5.4", _increasing([c.torque_slope_nm_per_deg for c in cfgs]), text, tuple(keys)
    )


def _stiffness_range(data: ReportData) -> Finding:
    title = "Stiffer springs shrink the reachable range"
    statement = (
        "By increasing the spring stiffness, the range of motion of the knee joint decreases because of the "
        "torque limitation on the robot (§5.4)."
    )
    keys = comparison_keys(data, "stiffness")
    cfgs = _sorted_by(_with_angles(data, keys), lambda c: _num(c, "stiffness_n_per_mm"))
    if len(cfgs) < 2:
        return _not_enough(title, statement, "5.4", keys, "two or more springs with processed data")
    ranges = [c.angle_max_deg - c.angle_min_deg for c in cfgs]
    # non-increasing within 1° of measurement slack, and the stiffest clearly below the softest
    agrees = all(b <= a + 1.0 for a, b in pairwise(ranges)) and ranges[-1] < ranges[0]
    text = "; ".join(
        f"config {c.key} ({_num(c, 'stiffness_n_per_mm'):.1f} N/mm): {c.angle_min_deg:.1f}-{c.angle_max_deg:.1f}°"
        for c in cfgs
    )
    return Finding(title, statement, "5.4", agrees, text, tuple(keys))


def _k2_upper_limit(data: ReportData) -> Finding:
    title = "With the medium spring (K2) the robot cannot pass about 110°"
    statement = (
        "The robot is unable to reach angles greater than 110°, since the maximum torque limit of the robot "
        "joint is reached at this point (§5.2, ranges [20°, 110°] and [0°, 130°])."
    )
    keys = comparison_keys(data, "brace_rom")
    cfgs = [c for c in _with_angles(data, keys) if _is_k2(c) and _upper(c.setting("brace_rom_deg")) >= 110.0]
    if not cfgs:
        return _not_enough(
            title, statement, "5.2", keys, "a K2 configuration with a brace stop at 110° or more"
        )
    agrees = all(c.angle_max_deg <= 110.0 + ANGLE_TOLERANCE_DEG for c in cfgs)
    text = "; ".join(f"config {c.key}: maximum angle reached {c.angle_max_deg:.1f}°" for c in cfgs)
    return Finding(title, statement, "5.2", agrees, text, tuple(c.key for c in cfgs))


def _r1_actual_range(data: ReportData) -> Finding:
    title = "A 40-90° brace stop lets the robot reach about 25-105°"
    statement = (
        "When the range was limited to [40°, 90°], actual output ranged from [25°, 105°], because the brace "
        "axis is not aligned with the robot knee axis (§5.2)."
    )
    keys = comparison_keys(data, "brace_rom")
    cfgs = [
        c
        for c in _with_angles(data, keys)
        if _stop(c.setting("brace_rom_deg")) == (40.0, 90.0) and _span(c.setting("robot_rom_deg")) > 50.0
    ]
    if not cfgs:
        return _not_enough(
            title, statement, "5.2", keys, "a configuration with a 40-90° stop and a wider trajectory"
        )
    agrees = all(
        abs(c.angle_min_deg - 25.0) <= ANGLE_TOLERANCE_DEG
        and abs(c.angle_max_deg - 105.0) <= ANGLE_TOLERANCE_DEG
        for c in cfgs
    )
    text = "; ".join(f"config {c.key}: reached {c.angle_min_deg:.1f}-{c.angle_max_deg:.1f}°" for c in cfgs)
    return Finding(title, statement, "5.2", agrees, text, tuple(c.key for c in cfgs))


def _is_k2(cfg: Configuration) -> bool:
    stiffness = cfg.setting("stiffness")
    if isinstance(stiffness, str) and stiffness.upper() in ("K2", "K-EMU", "KEMU"):
        return True
    return abs(_num(cfg, "stiffness_n_per_mm") - 13.0) < 0.5


def _upper(value: object) -> float:
    stop = _stop(value)
    return stop[1] if stop else math.nan


def _stop(value: object) -> tuple[float, float] | None:
    """A (low, high) pair of degrees from a 2-element setting, or None."""
    if not isinstance(value, tuple | list | np.ndarray) or len(value) != 2:
        return None
    try:
        return float(value[0]), float(value[1])
    except (TypeError, ValueError):
        return None
