"""The device under test as the simulated plant sees it: the protocol's elements (`models.elements`)
composed into the compiled kernel's inputs.

- elastic elements and masses (torques that depend on the angle alone) are summed, in declaration order,
  into one torque-vs-angle table (`models.element_torques.static_torque_nm`, every `spring_table_step_deg`
  over the joint range widened by 60° on both sides), linearly interpolated by the kernel;
- Coulomb brakes are grouped by their smoothing (transition, Stribeck excess and speed): a group's torques
  are summed and it has one Dahl state (brakes that share their smoothing are one friction surface as far
  as the equations go);
- viscous dampers are summed;
- one `rom_stops` element at most, and one `cuff_shift` at most (its height set by the lever springs'
  force, `element_torques.cuff_shift_height_nm`).

A mass element contributes its gravity torque; its inertia is neglected like the robot's own (the joint is
a speed source, docs/simulator.md).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.models.element_torques import cuff_shift_height_nm, has_static_torque, static_torque_nm
from protocol_runner.models.elements import Element, build_device

from .kernels import N_BRAKE_COLS

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ComposedDevice:
    """The kernel's view of a device. `table` is None without angle-only torques; `stops` is (lo, hi,
    slack, slack stiffness, stop stiffness) or None; `bump` is (angle, width, height, reference speed) or
    None."""

    elements: tuple[Element, ...]
    table_x0_deg: float
    table: FloatArray | None
    brakes: FloatArray  # (groups, N_BRAKE_COLS)
    damping_nm_s_per_deg: float
    stops: tuple[float, float, float, float, float] | None
    bump: tuple[float, float, float, float] | None


def as_elements(device: Sequence[object] | None) -> tuple[Element, ...]:
    """Elements from Element objects, ElementSetting-like objects or (name, type, params) tuples."""
    if device is None:
        return ()
    if all(isinstance(e, Element) for e in device):
        return tuple(e for e in device if isinstance(e, Element))
    return build_device(device)


def _single(elements: Sequence[Element], type_: str) -> Element | None:
    found = [e for e in elements if e.type == type_]
    if len(found) > 1:
        raise InvalidInput(
            f"device: the simulator takes one {type_} element, got {len(found)} ({', '.join(e.name for e in found)})"
        )
    return found[0] if found else None


def compose(
    elements: tuple[Element, ...], range_deg: tuple[float, float], table_step_deg: float
) -> ComposedDevice:
    """Compose `elements` for a joint of range `range_deg` (see the module docstring)."""
    static = [e for e in elements if has_static_torque(e)]
    lo = float(range_deg[0]) - 60.0
    table: FloatArray | None = None
    if static:
        n = math.ceil((float(range_deg[1]) + 60.0 - lo) / table_step_deg) + 1
        angles = lo + table_step_deg * np.arange(n, dtype=np.float64)
        table = np.zeros(n, dtype=np.float64)
        for e in static:
            table = table + static_torque_nm(e, angles)
        table = np.ascontiguousarray(table, dtype=np.float64)
    smoothing = ("transition_deg", "static_excess_ratio", "stribeck_speed_deg_s")
    groups: dict[tuple[float, ...], float] = defaultdict(float)
    for e in elements:
        if e.type == "coulomb_brake":
            groups[tuple(e.number(k) for k in smoothing)] += e.number("torque_nm")
    brakes = np.array([(t, *key) for key, t in groups.items()], dtype=np.float64).reshape(-1, N_BRAKE_COLS)
    damping = sum((e.number("damping_nm_s_per_deg") for e in elements if e.type == "viscous_damper"), 0.0)
    stops_el = _single(elements, "rom_stops")
    stops = None
    if stops_el is not None:
        s_lo, s_hi = stops_el.pair("range_deg")
        stops = (
            s_lo,
            s_hi,
            stops_el.number("slack_deg"),
            stops_el.number("slack_stiffness_nm_per_deg"),
            stops_el.number("stop_stiffness_nm_per_deg"),
        )
    cuff = _single(elements, "cuff_shift")
    bump = None
    if cuff is not None:
        height = cuff_shift_height_nm(cuff, [e for e in elements if e.type == "lever_spring"])
        bump = (
            cuff.number("angle_deg"),
            cuff.number("width_deg"),
            height,
            cuff.number("reference_speed_deg_s"),
        )
    return ComposedDevice(elements, lo, table, brakes, damping, stops, bump)
