"""The knee brace composed from elements reproduces the simulator's former knee-specific brace path bit for
bit: tests/hardware/data/knee_brace_baseline.npz holds the input codes recorded with `set_brace(BraceSetup(
rom, friction, stiffness, preload))` and the former knee defaults (seed 2007, a 9 s 10-120° sinusoid at
50 deg/s commanded from the 20° park angle: start-up transition, stops, stall at the torque limit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from protocol_runner.hardware.conversions import AI12_VOLTS_PER_CODE, angle_to_volts, torque_to_volts
from protocol_runner.hardware.simulator.daq import SimulatedRig

from ..knee_device import KNEE_PARAMS, knee_brace
from ..knee_rig import knee_joint_config

BASELINE = Path(__file__).resolve().parent / "data" / "knee_brace_baseline.npz"
CASES = {
    "off": None,
    "r3_f2_k2_p3": knee_brace((0.0, 130.0), 3.75, 13.0, 3),
    "r1_f3_k3_p1": knee_brace((40.0, 90.0), 6.25, 20.0, 1),
    "r2_f0_k0_p3": knee_brace((20.0, 110.0), 0.0, 0.0, 3),
    "re_f1_k1_p5": knee_brace((0.0, 110.0), 1.25, 4.4, 5),
}


@pytest.mark.parametrize("case", list(CASES))
def test_the_knee_brace_from_elements_gives_the_recorded_samples_exactly(case: str) -> None:
    joint = knee_joint_config(max_rate_deg_s=1000.0, max_accel_deg_s2=100_000.0)
    t = np.arange(900) / 100.0
    command = 65.0 + 55.0 * np.sin(2 * np.pi * t / (2 * np.pi * 55.0 / 50.0))
    sim = SimulatedRig([joint], seed=2007, params=KNEE_PARAMS)
    sim.set_device(CASES[case])
    sim.begin_step(f"baseline/{case}")
    rec = sim.make_rig().run_trajectory([command], where=case)[0]
    angle = np.rint(angle_to_volts(rec.angle_deg, joint.range_deg) / AI12_VOLTS_PER_CODE).astype(np.int16)
    torque = np.rint(torque_to_volts(rec.torque_nm, joint.torque_range_nm) / AI12_VOLTS_PER_CODE).astype(
        np.int16
    )
    with np.load(BASELINE) as recorded:
        np.testing.assert_array_equal(angle, recorded[f"{case}_angle_code"])
        np.testing.assert_array_equal(torque, recorded[f"{case}_torque_code"])
