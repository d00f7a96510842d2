"""The step kinds, run on their own: what each one reads and what it writes into its unit."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from protocol_runner.archive.results import comparison_values
from protocol_runner.archive.units import unit_path, write_unit
from protocol_runner.protocol.plan_steps import ChecklistStep, CompareStep, FitStep
from protocol_runner.session.operator import AutoOperator
from protocol_runner.steps import checklist, compare, fit
from protocol_runner.steps.context import StepContext
from protocol_runner.steps.registry import STEP_KINDS, run_function


def _context(units_dir: Path, **parts: object) -> StepContext:
    base: dict[str, object] = dict(
        loaded=None,
        plan=None,
        bench=None,
        operator=None,
        units_dir=units_dir,
        journal=None,
        stop_requested=lambda: False,
        processing=None,
    )
    base.update(parts)
    return StepContext(**base)  # type: ignore[arg-type]


def _processed_unit(
    units_dir: Path, key: int, energies: list[float], max_angle: float, joints: tuple[str, ...] = ("knee",)
) -> None:
    """A process unit keyed by joint: each joint's energies are `energies` times its position (1, 2, ...),
    their total is written beside them."""

    def fill(f: h5py.File) -> None:
        cfg = f.require_group(f"configurations/config_{key:02d}")
        for k, joint in enumerate(joints, start=1):
            part = cfg.require_group(f"joints/{joint}")
            part["energy_loss_j"] = k * np.asarray(energies)
            part["trials/1/processed/angle_deg"] = np.linspace(-max_angle, max_angle, 11) / k
        cfg["total_energy_loss_j"] = sum(range(1, len(joints) + 1)) * np.asarray(energies)
        cfg.attrs["joints"] = list(joints)

    write_unit(units_dir, f"process:k{key:02d}", fill)


def _campaign(*joints: str) -> SimpleNamespace:
    return SimpleNamespace(protocol=SimpleNamespace(driven_joints=joints))


def _written(outcome_fill, tmp_path: Path) -> h5py.File:
    path = tmp_path / "out.h5"
    with h5py.File(path, "w") as f:
        outcome_fill(f)
    return h5py.File(path, "r")


def test_every_step_kind_of_a_plan_has_its_function() -> None:
    kinds = {"calibration_check", "operator_checklist", "trial", "process", "fit", "compare"}
    assert set(STEP_KINDS) == kinds  # "report" is the runner's own: it consolidates the archive first


def test_compare_writes_mean_sample_std_count_and_largest_angle_of_each_configuration(tmp_path: Path) -> None:
    units = tmp_path / "units"
    _processed_unit(units, 1, [1.0, 2.0, 3.0], 40.0)
    _processed_unit(units, 2, [5.0], 60.0)
    step = CompareStep(
        id="compare:speed",
        kind="compare",
        name="speed",
        parameter="speed",
        title="Speed",
        section="5.1",
        configurations=(1, 2),
    )
    outcome = compare.run(step, _context(units, loaded=_campaign("knee")))
    with _written(outcome.fill, tmp_path) as f:
        assert list(f["comparisons/speed"].attrs["joints"]) == ["knee"]
        assert "energy_mean_j" not in f["comparisons/speed"].attrs  # one joint: its values are the joint's
        g = f["comparisons/speed/joints/knee"]
        assert list(g.attrs["configurations"]) == [1, 2]
        assert list(g.attrs["energy_mean_j"]) == [2.0, 5.0]
        assert g.attrs["energy_std_j"][0] == pytest.approx(1.0)  # sample std (ddof = 1) of 1, 2, 3
        assert np.isnan(g.attrs["energy_std_j"][1])  # one cycle: no spread
        assert list(g.attrs["energy_cycles"]) == [3, 1]
        assert list(g.attrs["max_angle_deg"]) == [40.0, 60.0]
    assert outcome.summary == "1: 2.00 J, 2: 5.00 J"


def test_compare_of_several_joints_compares_each_joint_and_their_total(tmp_path: Path) -> None:
    units = tmp_path / "units"
    _processed_unit(units, 1, [1.0, 2.0, 3.0], 40.0, joints=("hip", "knee"))
    _processed_unit(units, 2, [5.0], 60.0, joints=("hip", "knee"))
    step = CompareStep(
        id="compare:speed",
        kind="compare",
        name="speed",
        parameter="speed",
        title="Speed",
        section="5.1",
        configurations=(1, 2),
    )
    outcome = compare.run(step, _context(units, loaded=_campaign("hip", "knee")))
    with _written(outcome.fill, tmp_path) as f:
        g = f["comparisons/speed"]
        assert list(g.attrs["joints"]) == ["hip", "knee"]
        assert list(g.attrs["energy_mean_j"]) == [6.0, 15.0]  # the totals: hip's plus twice as much
        assert list(g["joints/hip"].attrs["energy_mean_j"]) == [2.0, 5.0]
        assert list(g["joints/knee"].attrs["energy_mean_j"]) == [4.0, 10.0]
        assert list(g["joints/knee"].attrs["max_angle_deg"]) == [20.0, 30.0]
    assert outcome.summary == "1: 6.00 J, 2: 15.00 J"


def test_compare_of_a_configuration_without_cycles_gives_nan_not_zero(tmp_path: Path) -> None:
    units = tmp_path / "units"
    _processed_unit(units, 3, [], 10.0)
    with h5py.File(unit_path(units, "process:k03"), "r") as f:
        values = comparison_values([f["configurations/config_03/joints/knee"]])
    assert np.isnan(values["energy_mean_j"][0]) and values["energy_cycles"] == [0]


def test_checklist_records_the_operators_answer_and_fits_the_brace(tmp_path: Path) -> None:
    fitted: list[object] = []
    bench = SimpleNamespace(fit_brace=fitted.append)
    step = ChecklistStep(
        id="check:A:brace-off",
        kind="operator_checklist",
        set="A",
        title="Remove the brace",
        items=("Take the brace off",),
        brace="off",
    )
    outcome = checklist.run(step, _context(tmp_path, operator=AutoOperator(), bench=bench))
    assert fitted == [None]  # brace off: nothing fitted to the joint
    with _written(outcome.fill, tmp_path) as f:
        g = f["session/checklists"]
        (name,) = list(g)
        attrs = g[name].attrs
        assert attrs["step_id"] == "check:A:brace-off"
        assert attrs["answer"] == "done" and bool(attrs["automatic"])
        assert json.loads(attrs["items"]) == ["Take the brace off"]  # lists are stored as JSON text


def test_fit_step_without_bouc_wen_writes_nothing(tmp_path: Path) -> None:
    step = FitStep(id="fit:k01", kind="fit", set="A", configuration=1, models=())
    outcome = fit.run(step, _context(tmp_path))
    assert outcome.fill is None and outcome.stop is None


def test_every_registered_step_function_is_a_function_of_the_steps_package() -> None:
    """The registry names its functions (their modules are imported when a step of the kind first runs):
    each name must be one, and the names follow the kinds (a misspelt name fails here, not in a session)."""
    from protocol_runner.steps import calibration_check, process, trial

    assert run_function("calibration_check") is calibration_check.run
    assert run_function("trial") is trial.run
    assert run_function("process") is process.run
    assert run_function("fit") is fit.run
    assert run_function("compare") is compare.run
    assert run_function("operator_checklist") is checklist.run
