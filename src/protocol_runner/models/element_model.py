"""The device's elements as a physical model of a measured loop (docs/analysis.md §10): at each sample of a
trial (angle θ, speed v)

    τ = Σ angle-only torques (elastic elements, masses' gravity)  +  range-of-motion stops
        + F  (one Dahl friction state for all Coulomb brakes together)  +  c · v  (all dampers together)

with every equation from :mod:`.element_torques`. Brakes on one hinge slide together, so the loop shows only
the *sum* of their torques: one friction term named after them all ("brake+hinge"), its level their sum,
its transition and Stribeck excess their torque-weighted means; dampers are summed likewise; the cuff shift
(an artefact) is left out. A :class:`ModelLayout` says which parameters are free; `values` maps (element,
parameter) to a number for the torque functions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from .element_torques import has_static_torque, static_torque_nm
from .element_types import ELEMENT_TYPES
from .elements import Element

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Key = tuple[str, str]  # (element, parameter)

FRICTION_PARAMS = ("torque_nm", "transition_deg")
DAMPER_PARAM = "damping_nm_s_per_deg"
SETTLE_DEG = 5.0  # travel at a trial's start left out of the fit (`Motion.settled`)
# Travel after each turning point left out of the fit (`Motion.from_samples`), also the branches' reversal
# threshold (`analysis.branches`)
REVERSAL_SKIP_DEG = 1.0


@njit(cache=True)
def unit_dahl_friction(
    angle_deg: FloatArray,
    speed_deg_s: FloatArray,
    edges: IntArray,
    transition_deg: float,
    excess_ratio: float,
    stribeck_speed_deg_s: float,
) -> tuple[FloatArray, FloatArray]:
    """The Dahl friction of a unit torque level along sampled motions placed end to end (trial i is
    samples edges[i]:edges[i+1]), and its derivative with respect to `transition_deg`.

    Between samples the state follows `element_torques.dahl_update` towards the level with the Stribeck
    excess at the sample's speed; each trial starts sliding in its first move's sense. The state is linear
    in the level, so a level T gives T times the first array."""
    n = angle_deg.shape[0]
    out = np.zeros(n)
    d_out = np.zeros(n)
    for t in range(edges.shape[0] - 1):
        a, b = edges[t], edges[t + 1]
        if b <= a:
            continue
        z = 0.0
        dz = 0.0
        for i in range(a + 1, b):
            if angle_deg[i] != angle_deg[a]:
                z = 1.0 if angle_deg[i] > angle_deg[a] else -1.0
                break
        out[a] = z
        for i in range(a + 1, b):
            step = angle_deg[i] - angle_deg[i - 1]
            if step != 0.0:
                vs = speed_deg_s[i] / stribeck_speed_deg_s
                level = 1.0 + excess_ratio * math.exp(-vs * vs)
                target = level if step > 0.0 else -level
                decay = math.exp(-abs(step) / transition_deg)
                # d/d(transition) of target + (z - target) * decay
                dz = (z - target) * decay * abs(step) / (transition_deg * transition_deg) + decay * dz
                z = target + (z - target) * decay
            out[i] = z
            d_out[i] = dz
    return out, d_out


def stops_torque_nm(e: Element, angle_deg: FloatArray) -> FloatArray:
    """A `rom_stops` element's torque at each angle (`element_torques.rom_stops_torque_nm`, vectorised)."""
    lo, hi = e.pair("range_deg")
    slack, slack_k, stop_k = (
        e.number("slack_deg"),
        e.number("slack_stiffness_nm_per_deg"),
        e.number("stop_stiffness_nm_per_deg"),
    )

    def one(pen: FloatArray) -> FloatArray:
        pen = np.maximum(pen, 0.0)
        return np.where(pen <= slack, slack_k * pen, slack_k * slack + stop_k * (pen - slack))

    return one(angle_deg - hi) - one(lo - angle_deg)


@dataclass(frozen=True)
class Motion:
    """One trial's motion and measured torque, in sample order. `settled`: the first sample the fit
    compares (after SETTLE_DEG of travel: the friction state at a trial's start is unknown, and the
    filtered loop's first samples carry the filter's edge). `reversing`: samples within
    REVERSAL_SKIP_DEG of travel after a turning point, not compared either (None: none)."""

    angle_deg: FloatArray
    speed_deg_s: FloatArray
    torque_nm: FloatArray
    settled: int = 0
    reversing: npt.NDArray[np.bool_] | None = None

    @property
    def compared(self) -> npt.NDArray[np.bool_]:
        """The samples a fit compares: from `settled` on, except those `reversing`."""
        keep = np.arange(self.angle_deg.size) >= self.settled
        return keep if self.reversing is None else keep & ~self.reversing

    @staticmethod
    def from_samples(
        time_s: npt.ArrayLike,
        angle_deg: npt.ArrayLike,
        torque_nm: npt.ArrayLike,
        *,
        max_step_deg: float | None = None,
        turning_points: Callable[[FloatArray, float], npt.NDArray[np.int64]] | None = None,
    ) -> Motion:
        """The motion of one trial's samples (those with a finite time, angle and torque).

        `max_step_deg`: keep every k-th sample only, k the largest keeping the median angle step within
        it (the Dahl update is exact over any monotone step); None keeps every sample. The speed is the
        central difference over the kept samples (over single samples the sensor noise biases a damper's
        coefficient toward zero). `turning_points(angle_deg, reversal_deg)` (`branches.turning_points`;
        None marks none): the samples within REVERSAL_SKIP_DEG of travel after each are `reversing`, where
        the equal-angle subtraction cannot follow the robot's own friction reversal."""
        t = np.asarray(time_s, dtype=np.float64)
        a = np.asarray(angle_deg, dtype=np.float64)
        y = np.asarray(torque_nm, dtype=np.float64)
        keep = np.isfinite(t) & np.isfinite(a) & np.isfinite(y)
        t, a, y = t[keep], a[keep], y[keep]
        travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(a)))])
        settled = int(np.searchsorted(travel, SETTLE_DEG))
        settled = settled if settled < a.size - 2 else 0
        reversing = np.zeros(a.size, dtype=bool)
        if turning_points is not None and a.size >= 3:
            ends = [*turning_points(a, REVERSAL_SKIP_DEG).tolist(), a.size]
            for start, stop in itertools.pairwise(ends):
                travel = np.maximum.accumulate(np.abs(a[start:stop] - a[start]))
                reversing[start : start + int(np.searchsorted(travel, REVERSAL_SKIP_DEG))] = True
        k = 1
        if max_step_deg is not None and a.size >= 2:
            median = float(np.median(np.abs(np.diff(a))))
            k = max(1, int(max_step_deg / median)) if median > 0 else 1
        t, a, y = t[::k], a[::k], y[::k]
        v = np.gradient(a, t) if a.size >= 2 else np.zeros_like(a)
        return Motion(a, v, y, -(-settled // k), reversing[::k])


@dataclass(frozen=True)
class Stacked:
    """Several trials' motions end to end, as the fit evaluates them (one call per element for all trials).
    Trial i is samples edges[i]:edges[i+1]; `compared` marks the samples a fit compares (each trial's
    `Motion.compared`)."""

    angle_deg: FloatArray
    speed_deg_s: FloatArray
    torque_nm: FloatArray
    edges: IntArray
    compared: npt.NDArray[np.bool_]

    @staticmethod
    def of(motions: Sequence[Motion]) -> Stacked:
        sizes = [m.angle_deg.size for m in motions]
        edges = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        compared = np.ones(int(edges[-1]), dtype=bool)
        for m, start in zip(motions, edges[:-1], strict=False):
            compared[start : start + m.angle_deg.size] = m.compared

        def joined(name: str) -> FloatArray:
            arrays = [getattr(m, name) for m in motions]
            return np.concatenate(arrays) if arrays else np.zeros(0)

        return Stacked(joined("angle_deg"), joined("speed_deg_s"), joined("torque_nm"), edges, compared)

    def split(self, values: FloatArray) -> list[FloatArray]:
        """`values` (one per sample) cut back into trials."""
        return [values[a:b] for a, b in itertools.pairwise(self.edges)]


@dataclass(frozen=True)
class ModelLayout:
    """The element model of one device: its elements, how the brakes and dampers are summed, and the
    free parameters (`free`, (element, parameter) pairs; the friction and damper sums under their
    joined names)."""

    elements: tuple[Element, ...]
    friction_name: str  # "" when the device has no brake
    friction_members: tuple[str, ...]
    damper_name: str
    damper_members: tuple[str, ...]
    free: tuple[Key, ...]
    declared: Mapping[Key, float]  # the device's value of every free parameter (sums for the friction/damper)
    excess_ratio: float
    stribeck_speed_deg_s: float

    def values(self, x: Sequence[float] | FloatArray) -> dict[Key, float]:
        out = dict(self.declared)
        out.update(zip(self.free, (float(v) for v in x), strict=True))
        return out


def _joined(elements: Sequence[Element]) -> str:
    return "+".join(e.name for e in elements)


def layout(elements: Sequence[Element], *, angle_deg: FloatArray | None = None) -> ModelLayout:
    """The element model of `elements`. An elastic element that gives no torque over `angle_deg` (a spring
    of stiffness 0) has nothing to fit and stays fixed."""
    elements = tuple(e for e in elements if e.kind != "artefact")
    brakes = [e for e in elements if e.type == "coulomb_brake"]
    dampers = [e for e in elements if e.type == "viscous_damper"]
    free: list[Key] = []
    declared: dict[Key, float] = {}
    probe = np.linspace(np.min(angle_deg), np.max(angle_deg), 64) if angle_deg is not None else None
    for e in elements:
        if e.kind != "elastic":
            continue
        if probe is not None and not np.any(static_torque_nm(e, probe) != 0.0):
            continue
        for p in e.fit:
            free.append((e.name, p))
            declared[(e.name, p)] = e.number(p)
    fname = _joined(brakes)
    total = sum(b.number("torque_nm") for b in brakes)
    weights = [b.number("torque_nm") / total if total > 0 else 1.0 / len(brakes) for b in brakes]

    def mean(p: str) -> float:
        return float(sum(w * b.number(p) for w, b in zip(weights, brakes, strict=True)))

    if brakes:
        declared[(fname, "torque_nm")] = float(total)
        declared[(fname, "transition_deg")] = mean("transition_deg")
        free += [(fname, p) for p in FRICTION_PARAMS]
    dname = _joined(dampers)
    if dampers:
        declared[(dname, DAMPER_PARAM)] = float(sum(d.number(DAMPER_PARAM) for d in dampers))
        free.append((dname, DAMPER_PARAM))
    return ModelLayout(
        elements=elements,
        friction_name=fname,
        friction_members=tuple(b.name for b in brakes),
        damper_name=dname,
        damper_members=tuple(d.name for d in dampers),
        free=tuple(free),
        declared=declared,
        excess_ratio=mean("static_excess_ratio") if brakes else 0.0,
        stribeck_speed_deg_s=mean("stribeck_speed_deg_s") if brakes else 1.0,
    )


def param_spec_key(lay: ModelLayout, key: Key) -> tuple[str, str]:
    """(element type, parameter) of a free parameter, for its registry entry."""
    name, param = key
    if name == lay.friction_name and lay.friction_members:
        return "coulomb_brake", param
    if name == lay.damper_name and lay.damper_members:
        return "viscous_damper", param
    etype = next(e.type for e in lay.elements if e.name == name)
    return etype, param


def elastic_torque_nm(lay: ModelLayout, values: Mapping[Key, float], angle_deg: FloatArray) -> FloatArray:
    """The angle-only torques (elastic elements with `values`, masses) and the stops at each angle."""
    total = np.zeros(angle_deg.shape, dtype=np.float64)
    for e in lay.elements:
        if has_static_torque(e):
            changed = {p: values[(e.name, p)] for p in e.fit if (e.name, p) in values}
            total += static_torque_nm(e.replace(**changed) if changed else e, angle_deg)
        elif e.type == "rom_stops":
            total += stops_torque_nm(e, angle_deg)
    return total


def unit_friction(
    lay: ModelLayout, values: Mapping[Key, float], stacked: Stacked
) -> tuple[float, FloatArray, FloatArray]:
    """The friction sum's level (kept >= 0; its transition > 0), its unit-level friction along `stacked`
    and that friction's derivative by the transition (`unit_dahl_friction`)."""
    level = max(values[(lay.friction_name, "torque_nm")], 0.0)
    transition = max(values[(lay.friction_name, "transition_deg")], 1e-6)
    args = (stacked.edges, transition, lay.excess_ratio, lay.stribeck_speed_deg_s)
    unit, d_unit = unit_dahl_friction(stacked.angle_deg, stacked.speed_deg_s, *args)
    return level, unit, d_unit


def stacked_torque_nm(lay: ModelLayout, values: Mapping[Key, float], stacked: Stacked) -> FloatArray:
    """The model's torque at every sample of `stacked` (module docstring)."""
    torque = elastic_torque_nm(lay, values, stacked.angle_deg)
    if lay.friction_members:
        level, unit, _ = unit_friction(lay, values, stacked)
        torque += level * unit
    if lay.damper_members:
        torque += values[(lay.damper_name, DAMPER_PARAM)] * stacked.speed_deg_s
    return torque


def model_torque_nm(lay: ModelLayout, values: Mapping[Key, float], motion: Motion) -> FloatArray:
    """The model's torque at every sample of one trial's `motion` (module docstring)."""
    return stacked_torque_nm(lay, values, Stacked.of([motion]))


def torque_jacobian(
    lay: ModelLayout, values: Mapping[Key, float], stacked: Stacked, step_sign: FloatArray
) -> FloatArray:
    """d(model torque)/d(free parameter) at every sample of `stacked`, one column per `lay.free` entry.

    Exact for the friction sum (the level's column is the unit-level friction; the transition's is the
    integrated derivative, `unit_dahl_friction`) and the damper sum (the speed). An elastic parameter's
    column is a forward difference of that element's torque alone, the step sqrt(machine epsilon) ·
    max(1, |value|) times `step_sign` (-1 where a step up would leave the parameter's bounds)."""
    n = stacked.angle_deg.size
    jac = np.empty((n, len(lay.free)))
    elastic: dict[str, list[int]] = {}
    unit = d_unit = np.zeros(0)
    level = 0.0
    for j, (name, param) in enumerate(lay.free):
        if lay.friction_members and name == lay.friction_name:
            if unit.size != n:
                level, unit, d_unit = unit_friction(lay, values, stacked)
            jac[:, j] = unit if param == "torque_nm" else level * d_unit
        elif lay.damper_members and name == lay.damper_name:
            jac[:, j] = stacked.speed_deg_s
        else:
            elastic.setdefault(name, []).append(j)
    rel = math.sqrt(float(np.finfo(np.float64).eps))
    for name, columns in elastic.items():
        e = next(el for el in lay.elements if el.name == name)
        current = {p: values[(name, p)] for p in e.fit if (name, p) in values}
        base = static_torque_nm(e.replace(**current), stacked.angle_deg)
        for j in columns:
            param = lay.free[j][1]
            stepped = current[param] + rel * max(1.0, abs(current[param])) * step_sign[j]
            moved = static_torque_nm(e.replace(**{**current, param: stepped}), stacked.angle_deg)
            jac[:, j] = (moved - base) / (stepped - current[param])
    return jac


MULTIPLICATIVE_UNITS = ("_nm", "_n_per_mm", "_nm_per_deg", "_nm_s_per_deg")


def transfer(lay_a: ModelLayout, lay_b: ModelLayout, fitted_a: Mapping[Key, float]) -> dict[Key, float]:
    """Configuration B's parameter values from A's fitted ones and the declared change A -> B.

    A parameter declared equal in A and B keeps A's fitted value. One that differs takes the declared
    factor (a torque, stiffness or damping: fitted_A · declared_B / declared_A) or the declared shift
    (an angle or a length: fitted_A + declared_B - declared_A). A parameter of B with no counterpart in A
    keeps B's declared value."""
    out = dict(lay_b.declared)
    for key, b_value in lay_b.declared.items():
        if key not in fitted_a or key not in lay_a.declared:
            continue
        a_value = lay_a.declared[key]
        fit = fitted_a[key]
        if a_value == b_value:
            out[key] = fit
            continue
        etype, param = param_spec_key(lay_b, key)
        unit = ELEMENT_TYPES[etype].parameters[param].unit
        if unit in MULTIPLICATIVE_UNITS and a_value != 0.0:
            out[key] = fit * b_value / a_value
        else:
            out[key] = fit + b_value - a_value
    return out
