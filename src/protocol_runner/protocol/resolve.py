"""A configuration's meaning: its factor levels resolved (through `same_as`), its device's element
parameters and its trajectory's fields bound to those levels' quantities (docs/protocol.md "Bindings").

`check_bindings` reports every binding problem of the protocol with its location (an undeclared factor, a
quantity whose unit suffix differs from the parameter's, an unknown element type or parameter, a level
lacking the bound quantity, a configuration that leaves a bound factor unset). `resolve_settings` and
`configuration_motion` assume a protocol that passed those checks.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InvalidInput
from ..models.element_types import ELEMENT_TYPES
from ..models.elements import build_element
from .schema import ConfigurationSpec, Protocol
from .settings import ElementSetting, FactorSetting, Quantity, Settings
from .trajectory_record import Trajectory
from .trajectory_specs import (
    PerJointSpec,
    RampedStepSpec,
    build_trajectory,
    is_binding,
    joint_spec,
    trajectory_bindings,
)
from .units import unit_suffix
from .yaml_doc import format_loc

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc, Problem


class BindingError(Exception):
    """A binding or element problem of one configuration; `message` does not name the configuration
    (validate.py merges the configurations that share a location and message into one line)."""

    def __init__(self, loc: Loc, message: str) -> None:
        super().__init__(message)
        self.loc = loc
        self.message = message


def resolve_factor(p: Protocol, factor: str, label: str) -> FactorSetting:
    """A factor at one level: quantities of the level (or of its `same_as` target), its own description
    and setup text or else the target's."""
    levels = p.factors[factor]
    level = levels[label]
    target = levels[level.same_as] if level.same_as is not None else level
    return FactorSetting(
        level=label,
        quantities=target.quantities,
        description=level.description or target.description,
        setup=level.setup or target.setup,
    )


def _bound_value(
    factors: Mapping[str, FactorSetting], binding: str, loc: Loc, cfg: ConfigurationSpec
) -> Quantity:
    factor, quantity = binding.split(".", 1)
    setting = factors.get(factor)
    if setting is None:
        raise BindingError(
            loc,
            f"bound to {binding} but the configuration sets no level of {factor!r}; give {factor} a level "
            "in the row, or in the generator's `fixed` or `baseline`",
        )
    value = setting.quantity(quantity)
    if value is None:
        have = ", ".join(q for q, _ in setting.quantities) or "no quantities"
        raise BindingError(
            loc,
            f"bound to {binding} but level {setting.level!r} of {factor} has no {quantity!r} (it has {have})",
        )
    return value


def resolve_device(
    p: Protocol, factors: Mapping[str, FactorSetting], cfg: ConfigurationSpec
) -> tuple[ElementSetting, ...]:
    """Every element with its parameters resolved and checked (defaults filled in, models/elements.py)."""
    if p.device is None:
        return ()
    out: list[ElementSetting] = []
    for joint, loc, el in p.device.located_elements():
        values: dict[str, Any] = {}
        for param, value in el.params.items():
            values[param] = _bound_value(factors, value, (*loc, param), cfg) if is_binding(value) else value
        try:
            built = build_element(el.name, el.type, values)
        except InvalidInput as exc:
            m = re.search(r"parameter '([^']+)'", exc.message)
            named = m.group(1) if m else None
            bound = el.params.get(named) if named is not None else None
            if named is not None and is_binding(bound):
                raise _bound_value_error(p, factors, str(bound), (*loc, named), exc.message) from None
            raise BindingError((*loc, named) if named else loc, exc.message) from None
        params = tuple((key, _setting_value(v)) for key, v in built.params.items())
        out.append(ElementSetting(name=el.name, type=el.type, params=params, joint=joint))
    return tuple(out)


def _setting_value(value: Any) -> Quantity | str:
    """An element parameter as the settings keep it: words joined by commas, numbers as floats."""
    if isinstance(value, tuple):
        return ",".join(value) if all(isinstance(x, str) for x in value) else tuple(float(x) for x in value)
    return value


def _bound_value_error(
    p: Protocol, factors: Mapping[str, FactorSetting], binding: str, param_loc: Loc, message: str
) -> BindingError:
    """A bound parameter's value is out of its element's bounds: the error names the level's quantity,
    where the value is written (the `same_as` target for an alias), and the parameter that binds it."""
    factor, quantity = binding.split(".", 1)
    label = factors[factor].level
    target = p.factors[factor][label].same_as or label
    return BindingError(
        ("factors", factor, target, quantity),
        f"{message} (level {target!r} of {factor}, bound by {format_loc(param_loc)})",
    )


def resolve_settings(p: Protocol, cfg: ConfigurationSpec) -> Settings:
    """The configuration's factors (declaration order) and its resolved device. Raises BindingError."""
    labels = cfg.levels
    factors = [(f, resolve_factor(p, f, labels[f])) for f in p.factors if f in labels]
    return Settings(factors=tuple(factors), device=resolve_device(p, dict(factors), cfg))


def trajectory_values(
    p: Protocol, settings: Settings, cfg: ConfigurationSpec, joint: str
) -> dict[str, Quantity]:
    """The bound fields' values of the configuration's trajectory (of `joint`'s entry of a `per_joint`)."""
    spec, prefix = joint_spec(p.trajectories[cfg.trajectory], joint)
    factors = dict(settings.factors)
    return {
        field: _bound_value(factors, binding, ("trajectories", cfg.trajectory, *prefix, field), cfg)
        for field, binding in trajectory_bindings(spec).items()
    }


def configuration_motion(
    loaded: LoadedProtocol, cfg: ConfigurationSpec, settings: Settings
) -> tuple[tuple[str, Trajectory], ...]:
    """What a configuration commands: (joint, trajectory) per driven joint in channel order. The joints
    of a protocol that names `joints:` each need their motion (`per_joint`, or a file with a column per
    joint), all lasting the same number of output ticks; InvalidInput (naming the joint) or BindingError
    if it cannot be built."""
    from .stream_check import safety_limits

    p = loaded.protocol
    name = cfg.trajectory
    spec = p.trajectories[name]
    if p.multi_joint and not isinstance(spec, PerJointSpec) and spec.kind != "file":
        raise InvalidInput(
            f"trajectory {name!r} ({spec.kind}): a multi-joint trial needs each joint's motion: give "
            "`kind: per_joint` with one entry per driven joint, or a `file` with one angle column per joint"
        )
    if not p.multi_joint and isinstance(spec, PerJointSpec):
        raise InvalidInput(
            f"trajectory {name!r}: kind per_joint needs a multi-joint protocol (`joints: [...]`)"
        )
    out: list[tuple[str, Trajectory]] = []
    for joint in p.driven_joints:
        values = trajectory_values(p, settings, cfg, joint)
        limits = safety_limits(p.rig_of(joint))
        try:
            traj = build_trajectory(
                name, joint_spec(spec, joint)[0], values, loaded.base_dir, joint=joint, limits=limits
            )
        except InvalidInput as exc:
            raise InvalidInput(f"joint {joint}: {exc.message}" if p.multi_joint else exc.message) from None
        out.append((joint, traj))
    rate = p.rig.output.rate_hz
    ticks = {j: len(np.arange(0.0, t.duration_s, 1.0 / rate)) for j, t in out} if len(out) > 1 else {}
    if len(set(ticks.values())) > 1:
        shown = ", ".join(f"{j} {n} ({dict(out)[j].duration_s:g} s)" for j, n in ticks.items())
        raise InvalidInput(
            f"trajectory {name!r}: the joints of a trial share its time, but their motions last different "
            f"numbers of output ticks at {rate:g} Hz: {shown}"
        )
    return tuple(out)


def calibration_trajectory(p: Protocol, joint: str | None = None) -> Trajectory:
    """The calibration check's ramped step (of `joint`, default the first driven joint)."""
    step = p.calibration_step_of(joint or p.driven_joints[0])
    spec = RampedStepSpec(kind="ramped_step", **step.model_dump())
    return build_trajectory("calibration_step", spec, {}, Path("."))


def check_bindings(p: Protocol) -> Iterator[Problem]:
    """Static checks of every binding and element (before any configuration is resolved), of the device's
    form (elements per joint when several joints are driven) and of `per_joint` trajectories' joints."""
    yield from _check_joints_named(p)
    if p.device is not None:
        names: set[tuple[str, str]] = set()
        for joint, loc, el in p.device.located_elements():
            if (joint, el.name) in names:
                yield (*loc, "name"), f"element name {el.name!r} is used twice"
            names.add((joint, el.name))
            etype = ELEMENT_TYPES.get(el.type)
            if etype is None:
                yield (
                    (*loc, "type"),
                    f"unknown element type {el.type!r}{_did_you_mean(el.type, ELEMENT_TYPES)} "
                    f"(known: {', '.join(ELEMENT_TYPES)})",
                )
                continue
            meant: set[str] = set()  # a misspelt parameter is one mistake, not also a missing one
            for param, value in el.params.items():
                spec = etype.parameters.get(param)
                if spec is None:
                    close = difflib.get_close_matches(param, list(etype.parameters), n=1, cutoff=0.75)
                    meant.update(close)
                    yield (
                        (*loc, param),
                        f"unknown parameter of {el.type}{_did_you_mean(param, etype.parameters)} "
                        f"(parameters: {', '.join(etype.parameters)})",
                    )
                elif is_binding(value):
                    yield from _check_binding(p, value, spec.unit, (*loc, param))
            for param, spec in etype.parameters.items():
                if spec.default is None and param not in el.params and param not in meant:
                    yield (*loc,), f"missing required parameter {param!r} of {el.type} ({spec.doc})"
    for name, tspec in p.trajectories.items():
        for field, binding in trajectory_bindings(tspec).items():
            parts = tuple(field.split("."))
            yield from _check_binding(
                p, binding, unit_suffix(parts[-1]) or "", ("trajectories", name, *parts)
            )


def _check_joints_named(p: Protocol) -> Iterator[Problem]:
    """A device of several driven joints is declared per joint, for driven joints only; a `per_joint`
    trajectory has an entry for every driven joint and for no other."""
    driven = p.driven_joints
    if p.device is not None and p.device.elements and len(driven) > 1:
        yield (
            ("device", "elements"),
            f"this campaign drives {len(driven)} joints ({', '.join(driven)}): a flat `elements` list would "
            "put every element on every joint; give each joint its own under `device.joints.<joint>.elements`",
        )
    if p.device is not None:
        yield from joints_named(("device", "joints"), p.device.joints, driven)
    for name, spec in p.trajectories.items():
        if isinstance(spec, PerJointSpec) and p.multi_joint:
            yield from joints_named(("trajectories", name, "joints"), spec.joints, driven, "entry")


def joints_named(loc: Loc, named: Iterable[str], driven: Sequence[str], each: str = "") -> Iterator[Problem]:
    """The keys `named` of the mapping at `loc` against the driven joints: every key that is not one, and,
    when every driven joint needs `each` (its entry, its calibration step), the driven joints missing."""
    named = list(named)
    shown = ", ".join(driven)
    for joint in named:
        if joint not in driven:
            yield (*loc, joint), f"{joint!r} is not one of the driven joints ({shown})"
    missing = [j for j in driven if j not in named]
    if each and missing:
        yield loc, f"no {each} for driven joint(s) {', '.join(missing)} (joints: {shown})"


def _did_you_mean(word: str, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.75)  # as `meant` above
    return f"; did you mean {close[0]!r}?" if close else ""


def _check_binding(p: Protocol, binding: str, unit: str, loc: Loc) -> Iterator[Problem]:
    factor, quantity = binding.split(".", 1)
    if factor not in p.factors:
        yield (
            loc,
            f"bound to {binding}: no factor {factor!r} is declared (factors: {', '.join(p.factors) or 'none'})",
        )
        return
    got = unit_suffix(quantity)
    if got != unit:
        yield (
            loc,
            (
                f"bound to {binding}, whose unit suffix is {got or 'missing'!s}; this parameter needs a "
                f"quantity ending with {unit or '(no unit)'}"
            ),
        )
        return
    if not any(quantity in dict(lv.quantities) for lv in p.factors[factor].values()):
        has = list(dict.fromkeys(q for lv in p.factors[factor].values() for q, _ in lv.quantities))
        shown = f" (its levels have {', '.join(has)})" if has else " (its levels have no quantities)"
        yield loc, f"bound to {binding}: no level of {factor} has a quantity {quantity!r}{shown}"
