"""The element fit (analysis/element_fit.py) recovers the elastic elements' parameters from data simulated
with known ones, and says "not applicable" when the device has nothing elastic to fit."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.element_fit import fit_elements, model_torque_nm
from protocol_runner.analysis.pipeline import Recording, TrialPair, process_configuration
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.models.elements import build_device

from ..knee_rig import knee_joint_config

TRUE = {"torsion": (0.3, 40.0), "cord": (0.6, 75.0)}


def device(torsion: tuple[float, float], cord: tuple[float, float], **extra: object) -> list:
    return [
        ("torsion", "torsion_spring", {"stiffness_nm_per_deg": torsion[0], "neutral_deg": torsion[1]}),
        ("cord", "bungee", {"stiffness_nm_per_deg": cord[0], "slack_deg": cord[1], "direction": 1, **extra}),
        ("brake", "coulomb_brake", {"torque_nm": 2.0, "transition_deg": 1.5}),
    ]


def _loop(noise_nm: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 24.0, 2e-3)
    angle = 65.0 + 45.0 * np.sin(2 * np.pi * t / 6.0)
    elastic = model_torque_nm(build_device(device(TRUE["torsion"], TRUE["cord"])), angle)
    friction = 2.0 * np.sign(np.cos(2 * np.pi * t / 6.0))
    return angle, elastic + friction + np.random.default_rng(4).normal(0.0, noise_nm, t.shape)


def test_a_torsion_spring_and_a_bungee_are_recovered_from_wrong_declared_values() -> None:
    angle, torque = _loop()
    fit = fit_elements(angle, torque, device((0.1, 0.0), (0.2, 60.0)))
    assert fit.applicable and fit.reason == "least squares on the loop midline"
    assert fit.value("torsion", "stiffness_nm_per_deg") == pytest.approx(0.3, rel=0.02)
    assert fit.value("torsion", "neutral_deg") == pytest.approx(40.0, abs=1.0)
    assert fit.value("cord", "stiffness_nm_per_deg") == pytest.approx(0.6, rel=0.03)
    assert fit.value("cord", "slack_deg") == pytest.approx(75.0, abs=1.0)
    assert fit.rmse_nm < 0.3 < fit.rmse_all_samples_nm  # the midline cancels the brake's ±2 N·m
    assert [e.name for e in fit.elements] == ["torsion", "cord"]  # the brake is not an elastic element


def test_only_the_listed_parameters_are_fitted() -> None:
    angle, torque = _loop()
    fit = fit_elements(angle, torque, device(TRUE["torsion"], (0.6, 60.0), fit=["slack_deg"]))
    assert [(e, p) for e, p, _ in fit.fitted] == [
        ("torsion", "stiffness_nm_per_deg"),
        ("torsion", "neutral_deg"),
        ("cord", "slack_deg"),
    ]
    assert fit.value("cord", "slack_deg") == pytest.approx(75.0, abs=1.0)
    assert fit.elements[1].number("stiffness_nm_per_deg") == 0.6


def test_a_device_with_no_elastic_element_is_not_applicable() -> None:
    angle, torque = _loop()
    dissipative = [
        ("brake", "coulomb_brake", {"torque_nm": 2.0}),
        ("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.02}),
        ("stops", "rom_stops", {"range_deg": [0, 130], "stop_stiffness_nm_per_deg": 40}),
    ]
    fit = fit_elements(angle, torque, dissipative)
    assert not fit.applicable and fit.reason == "not applicable: the device has no elastic element to fit"
    assert np.isnan(fit.rmse_nm) and fit.fitted == ()


def test_elements_simulated_on_a_generic_joint_are_recovered_through_the_processing() -> None:
    """End to end: the simulator (generic robot-side defaults, no knee values) carries a torsion spring,
    a bungee and a brake; the processing subtracts the brace-off run and fits the two elastic elements."""
    joint = knee_joint_config(max_rate_deg_s=1000.0, max_accel_deg_s2=100_000.0)
    params = SimulatorParams(gravity_torque_max_nm=10.0, robot_friction_nm=1.0)
    t = np.arange(round(4 * 2 * np.pi * 45.0 / 40.0 * 100)) / 100.0
    command = 65.0 + 45.0 * np.sin(2 * np.pi * t / (2 * np.pi * 45.0 / 40.0))
    recordings = []
    for dev in (device(TRUE["torsion"], TRUE["cord"]), None):
        sim = SimulatedRig([joint], seed=11, params=params)
        sim.set_device(dev)
        sim.begin_step(f"fit/{dev is None}")
        r = sim.make_rig().run_trajectory([command], where="fit")[0]
        recordings.append(
            Recording(r.input_time_s, r.angle_deg, r.torque_nm, r.command_deg, r.command_time_s)
        )
    result = process_configuration([TrialPair(*recordings)], device=device((0.1, 0.0), (0.2, 60.0)))
    fit = result.elements
    assert fit is not None and fit.applicable
    assert fit.value("torsion", "stiffness_nm_per_deg") == pytest.approx(0.3, rel=0.05)
    assert fit.value("torsion", "neutral_deg") == pytest.approx(40.0, abs=2.0)
    assert fit.value("cord", "stiffness_nm_per_deg") == pytest.approx(0.6, rel=0.08)
    assert fit.value("cord", "slack_deg") == pytest.approx(75.0, abs=2.0)
