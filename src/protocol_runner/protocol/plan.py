"""Expansion of a protocol into a Plan: plain immutable data, ordered as executed, with stable step ids.

Order (thesis Appendix A "Data collection": the brace is removed only after each set):

    for each set, in test-run order:
        calibration check before (45 deg step)
        for each configuration: operator checklist (brace settings), brace-on trials 1..n
        operator checklist: remove the brace
        for each configuration: brace-off trials 1..n (input derived at run time from the brace-on output,
                                §3.3.2), each the twin of the brace-on trial with the same number
        calibration check after
        for each configuration: processing, then model fits      (results as soon as the data exist)
    cross-configuration comparisons
    report

Step ids are the resume keys: they depend only on the protocol's names and keys, never on time or on
`--only`, so the same step has the same id in every run.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from .loaded import LoadedProtocol
from .only import KeySelection
from .plan_steps import (
    CalibrationCheckStep,
    ChecklistStep,
    CompareStep,
    FitStep,
    JointTrajectories,
    Plan,
    ProcessStep,
    ReportStep,
    Step,
    TrialStep,
)
from .resolve import calibration_trajectory, configuration_motion, resolve_settings
from .schema import ConfigurationSpec, Protocol, SetSpec
from .settings import Settings
from .step_ids import calibration_id, step_id, trial_id
from .trajectory_record import Trajectory
from .units import unit_text


def _quantity_text(name: str, value: float | tuple[float, ...]) -> str:
    unit = unit_text(name)
    # a pair reads "from -38 to 24" (a dash would make "-38-24" of a negative range); a list is comma-separated
    if isinstance(value, tuple):
        shown = (
            f"from {value[0]:g} to {value[1]:g}" if len(value) == 2 else ", ".join(f"{v:g}" for v in value)
        )
    else:
        shown = f"{value:g}"
    return f"{name} = {shown}{' ' + unit if unit and unit != '%' else unit}"


def _setup_items(p: Protocol, st: Settings) -> tuple[str, ...]:
    """One checklist item per factor (its level, quantities with units, description and setup text),
    then the protocol's bolt torques and the fitting check."""
    items = []
    for factor, f in st.factors:
        quantities = ", ".join(_quantity_text(q, v) for q, v in f.quantities)
        text = f"{factor} {f.level}"
        if quantities:
            text += f" ({quantities})"
        if f.setup:
            text += f": {f.setup}"
        if f.description:
            text += f" [{f.description}]"
        items.append(text)
    items += [f"Tighten {b.bolts} to {b.torque_ft_lb:g} ft-lb" for b in p.bolt_torques]
    device = p.device.name if p.device is not None and p.device.name else "the device"
    items.append(f"{device[:1].upper() + device[1:]} on the robot, secured and not shifting")
    return tuple(items)


def expand(loaded: LoadedProtocol, only: KeySelection | Iterable[int] | None = None) -> Plan:
    """Expand a validated protocol into its Plan; `only` restricts it to those configuration keys."""
    p = loaded.protocol
    all_keys = [c.key for _, c in p.configurations()]
    selected: set[int] | None = None
    if only is not None:
        chosen_keys = (
            only if isinstance(only, KeySelection) else KeySelection(tuple((int(k), int(k)) for k in only))
        )
        selected = set(chosen_keys.select(all_keys, loaded.path.name))
    steps: list[Step] = []
    cal_traj = calibration_trajectory(p)
    for s in p.sets:
        cfgs = [c for c in s.configurations if selected is None or c.key in selected]
        if cfgs:
            steps += _expand_set(p, loaded, s, cfgs, cal_traj)
    chosen = [k for k in all_keys if selected is None or k in selected]
    for comp in p.report.comparisons:
        keys = tuple(k for k in comp.configurations if k in chosen)
        if len(keys) >= 2:
            fields = comp.model_dump(include={"name", "parameter", "title", "section"})
            steps.append(
                CompareStep(id=step_id("compare", comp.name), kind="compare", configurations=keys, **fields)
            )
    steps.append(ReportStep(id=step_id("report"), kind="report"))
    return Plan(
        protocol_name=p.name,
        protocol_sha256=loaded.sha256,
        steps=tuple(steps),
        only=tuple(sorted(selected)) if selected is not None else (),
    )


def _trial(
    s: SetSpec, cfg: ConfigurationSpec, st: Settings, motion: JointTrajectories, brace: str, n: int
) -> TrialStep:
    """Trial n of a configuration; a brace-off trial names its brace-on twin (its input comes from it).
    `motion`: (joint, trajectory) per driven joint of a multi-joint protocol, else ("", trajectory)."""
    return TrialStep(
        id=trial_id(cfg.key, brace, n),
        kind="trial",
        set=s.name,
        configuration=cfg.key,
        run=cfg.run,
        trial=n,
        brace=brace,
        settings=st,
        trajectory=motion[0][1],
        twin=trial_id(cfg.key, "on", n) if brace == "off" else None,
        joint_trajectories=motion if motion[0][0] else (),
    )


def _expand_set(
    p: Protocol, loaded: LoadedProtocol, s: SetSpec, cfgs: list[ConfigurationSpec], cal_traj: Trajectory
) -> list[Step]:
    cal_joints: JointTrajectories = (
        tuple((j, calibration_trajectory(p, j)) for j in p.driven_joints) if p.multi_joint else ()
    )

    def calibration_check(when: str) -> CalibrationCheckStep:
        return CalibrationCheckStep(
            id=calibration_id(s.name, when),
            kind="calibration_check",
            set=s.name,
            when=when,
            trajectory=cal_traj,
            joint_trajectories=cal_joints,
        )

    steps: list[Step] = [calibration_check("before")]
    resolved = [(c, resolve_settings(p, c)) for c in cfgs]
    trajectories: dict[int, JointTrajectories] = {
        c.key: tuple((j if p.multi_joint else "", t) for j, t in configuration_motion(loaded, c, st))
        for c, st in resolved
    }
    device = p.device.name if p.device is not None and p.device.name else "device"
    for cfg, st in resolved:
        steps.append(
            ChecklistStep(
                id=step_id("check", set_name=s.name, key=cfg.key),
                kind="operator_checklist",
                set=s.name,
                title=f"Configuration {cfg.key} (test run {cfg.run}): set up the {device}",
                items=_setup_items(p, st),
                brace="on",
                configuration=cfg.key,
                settings=st,
            )
        )
        steps += [_trial(s, cfg, st, trajectories[cfg.key], "on", n) for n in range(1, cfg.trials + 1)]
    steps.append(
        ChecklistStep(
            id=step_id("check", "brace-off", set_name=s.name),
            kind="operator_checklist",
            set=s.name,
            title=f"Set {s.name}: remove the {device}; the robot runs the same conditions without it",
            items=(
                f"Remove the {device} from the robot (keep its settings untouched)",
                "Robot segment free of straps, foam and clamps",
            ),
            brace="off",
        )
    )
    for cfg, st in resolved:
        steps += [_trial(s, cfg, st, trajectories[cfg.key], "off", n) for n in range(1, cfg.trials + 1)]
    steps.append(calibration_check("after"))
    # the spring model is fitted by the processing step; the fit step is the Bouc-Wen model's (per joint
    # that carries elements, in a multi-joint protocol)
    models = ("bouc_wen",) if p.fits.bouc_wen.enabled else ()
    for cfg, _ in resolved:
        pairs = tuple(
            (trial_id(cfg.key, "on", n), trial_id(cfg.key, "off", n)) for n in range(1, cfg.trials + 1)
        )
        steps.append(ProcessStep(**_analysis_fields("process", s, cfg), trials=pairs))
        if models:
            steps.append(FitStep(**_analysis_fields("fit", s, cfg), models=models))
    return steps


def _analysis_fields(kind: str, s: SetSpec, cfg: ConfigurationSpec) -> dict[str, Any]:
    """The fields a configuration's analysis step (process, fit) shares: its id, kind, set and key."""
    return {"id": step_id(kind, key=cfg.key), "kind": kind, "set": s.name, "configuration": cfg.key}
