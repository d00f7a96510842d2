"""Between-trial spread of the simulated rig: each trial draws its own robot and device friction (a real
rig is not the same from one trial to the next), from the session seed and the trial, so that a seed still
fixes every value and a brace-off trial subtracts the robot that ran its brace-on twin."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.simulator.kernels import B_TORQUE, P_DAMPING, P_ROBOT_F, P_ROBOT_VISC
from protocol_runner.hardware.simulator.params import SimulatorParams, trial_factors
from protocol_runner.protocol.step_ids import trial_id, trial_of

from ..knee_device import KNEE_PARAMS, knee_brace
from ..knee_rig import knee_joint_config

KNEE = knee_joint_config(max_rate_deg_s=1000.0, max_accel_deg_s2=1e6)
SPREAD = replace(
    KNEE_PARAMS,
    trial_spread_robot_friction_cv=0.05,
    trial_spread_robot_viscous_cv=0.05,
    trial_spread_device_friction_cv=0.03,
)


def frictions(sim: SimulatedRig) -> tuple[float, float, float, float]:
    """(robot Coulomb N·m, robot viscous, first brake group's torque, device damping) the plant uses now."""
    p, brakes = sim.plant()._p, sim.plant()._brakes
    return (
        float(p[P_ROBOT_F]),
        float(p[P_ROBOT_VISC]),
        float(brakes[0, B_TORQUE]) if brakes.shape[0] else 0.0,
        float(p[P_DAMPING]),
    )


def test_the_factors_have_mean_one_and_the_declared_spread() -> None:
    """Log-normal factors: always positive, mean 1, coefficient of variation as declared (20,000 draws:
    the sample CV is within 3 % of its value)."""
    rng = np.random.default_rng(1)
    draws = np.array([trial_factors(SPREAD, rng) for _ in range(20_000)])
    assert np.all(draws > 0.0)
    assert np.allclose(draws.mean(axis=0), 1.0, atol=0.002)
    cv = draws.std(axis=0) / draws.mean(axis=0)
    assert np.allclose(cv, (0.05, 0.05, 0.03), rtol=0.03)


def test_no_spread_leaves_every_value_exactly_as_declared() -> None:
    """CVs of 0 (the defaults): every trial has exactly the declared friction (multiplied by 1.0)."""
    assert trial_factors(KNEE_PARAMS, np.random.default_rng(5)) == (1.0, 1.0, 1.0)
    sim = SimulatedRig([KNEE], seed=3, params=KNEE_PARAMS)
    sim.set_device(knee_brace((0.0, 130.0), 3.75, 13.0))
    sim.begin_step("trial:k01:on:1", "trial:k01:on:1")
    assert frictions(sim)[:2] == (2.5, 0.03)
    assert frictions(sim)[2] == 3.75 + 0.75  # the brake and the hinge share one Dahl state


def test_a_trial_and_its_brace_off_twin_see_the_same_draw_other_trials_another() -> None:
    on, off, other = trial_id(4, "on", 2), trial_id(4, "off", 2), trial_id(4, "on", 3)
    assert trial_of(off) == on and trial_of(on) == on and trial_of("cal:A:before") == "cal:A:before"
    sim = SimulatedRig([KNEE], seed=7, params=SPREAD)
    sim.set_device(knee_brace((0.0, 130.0), 3.75, 13.0))
    sim.begin_step(on, trial_of(on))
    brace_on = frictions(sim)
    sim.set_device(None)
    sim.begin_step(off, trial_of(off))
    brace_off = frictions(sim)
    assert brace_off[:2] == brace_on[:2]  # the same robot
    assert brace_off[2:] == (0.0, 0.0)  # no device
    sim.set_device(knee_brace((0.0, 130.0), 3.75, 13.0))
    sim.begin_step(other, trial_of(other))
    assert frictions(sim) != brace_on
    assert all(abs(x / 2.5 - 1.0) < 0.3 for x in (brace_on[0], frictions(sim)[0]))


def test_the_draw_depends_on_the_seed_and_trial_only() -> None:
    """A resume (a fresh simulator that ran other steps first, with the device fitted after begin_step)
    gives the same values as the uninterrupted run; another seed gives others."""
    device = knee_brace((0.0, 130.0), 3.75, 13.0)
    a = SimulatedRig([KNEE], seed=7, params=SPREAD)
    a.set_device(device)
    a.begin_step("trial:k02:on:1", "trial:k02:on:1")
    b = SimulatedRig([KNEE], seed=7, params=SPREAD)
    b.begin_step("cal:A:before")
    b.begin_step("trial:k02:on:1", "trial:k02:on:1")
    b.set_device(device)
    c = SimulatedRig([KNEE], seed=8, params=SPREAD)
    c.set_device(device)
    c.begin_step("trial:k02:on:1", "trial:k02:on:1")
    assert frictions(a) == frictions(b) != frictions(c)


def test_the_spread_scales_dampers_but_not_springs() -> None:
    sim = SimulatedRig([KNEE], seed=7, params=SPREAD)
    damper = ("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.1})
    sim.set_device([*knee_brace((0.0, 130.0), 3.75, 13.0), damper])
    table = sim.plant()._table.copy()
    sim.begin_step("t", "t")
    factor = trial_factors(SPREAD, np.random.default_rng(_spread_seed(7, "t")))[2]
    assert frictions(sim)[3] == pytest.approx(0.1 * factor, rel=1e-12)
    assert frictions(sim)[2] == pytest.approx(4.5 * factor, rel=1e-12)
    assert np.array_equal(sim.plant()._table, table)


def _spread_seed(seed: int, trial: str) -> int:
    from protocol_runner.hardware.simulator.daq import spread_seed

    return spread_seed(seed, trial)


def test_a_spread_beyond_half_is_refused() -> None:
    with pytest.raises(InvalidInput, match="trial_spread_device_friction_cv"):
        SimulatorParams(trial_spread_device_friction_cv=0.8)
