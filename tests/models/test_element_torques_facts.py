"""Each device element's torque equation (models/element_torques.py) against a physical fact."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.models.element_torques import (
    dahl_update,
    has_static_torque,
    rom_stops_torque_nm,
    static_torque_nm,
    stribeck_level_nm,
    viscous_torque_nm,
)
from protocol_runner.models.elements import ELEMENT_TYPES, build_element

from ..knee_device import lever_spring

# one cycle of a sinusoid: angle = A sin(ωt), A in degrees
AMPLITUDE_DEG = 30.0
PERIOD_S = 4.0
N = 40_001
T = np.linspace(0.0, PERIOD_S, N)
OMEGA = 2.0 * np.pi / PERIOD_S
ANGLE = 50.0 + AMPLITUDE_DEG * np.sin(OMEGA * T)
SPEED = AMPLITUDE_DEG * OMEGA * np.cos(OMEGA * T)
A_RAD = np.radians(AMPLITUDE_DEG)


def loop_energy_j(angle_deg: np.ndarray, torque_nm: np.ndarray) -> float:
    """∮ τ dθ (θ in rad): the energy the robot puts into the element over the path."""
    return float(np.sum(0.5 * (torque_nm[1:] + torque_nm[:-1]) * np.diff(np.radians(angle_deg))))


ELASTIC = {
    "lever_spring": lever_spring(13.0, 3),
    "torsion_spring": ("t", "torsion_spring", {"stiffness_nm_per_deg": 0.4, "neutral_deg": 35.0}),
    "bungee": ("b", "bungee", {"stiffness_nm_per_deg": 0.8, "slack_deg": 55.0, "direction": -1}),
    "mass": ("m", "mass", {"mass_kg": 3.0, "lever_m": 0.2, "hanging_deg": 10.0}),
}


def test_every_angle_only_element_is_covered_here() -> None:
    assert {n for n, t in ELEMENT_TYPES.items() if t.kind == "elastic" or n == "mass"} == set(ELASTIC)


@pytest.mark.parametrize("kind", list(ELASTIC))
def test_a_conservative_elements_loop_encloses_no_energy(kind: str) -> None:
    element = build_element(*ELASTIC[kind])
    assert has_static_torque(element)
    torque = static_torque_nm(element, ANGLE)
    half = N // 4  # a quarter period: the angle rises from the mean to the top
    one_way = abs(loop_energy_j(ANGLE[:half], torque[:half]))
    assert one_way > 0.05  # the element does work on the way up ...
    assert abs(loop_energy_j(ANGLE, torque)) < 1e-9 * max(1.0, one_way)  # ... and gives it all back


def test_a_brake_loses_4_t_a_per_cycle() -> None:
    """Coulomb friction T over a sinusoid of amplitude A (rad): 4·T·A per cycle (Dahl transition small,
    no Stribeck excess). The state is taken through two cycles; the second is measured."""
    torque_nm = 3.75
    angle = np.concatenate([ANGLE, ANGLE[1:]])
    z = np.zeros(angle.shape[0])
    for i in range(1, angle.shape[0]):
        z[i] = dahl_update(z[i - 1], torque_nm, angle[i] - angle[i - 1], 0.01)
    energy = loop_energy_j(angle[N - 1 :], z[N - 1 :])
    assert energy == pytest.approx(4.0 * torque_nm * A_RAD, rel=2e-3)


def test_the_brakes_stribeck_excess_is_friction_at_standstill_only() -> None:
    assert stribeck_level_nm(2.0, 0.0, 0.3, 20.0) == pytest.approx(2.6)
    assert stribeck_level_nm(2.0, 200.0, 0.3, 20.0) == pytest.approx(2.0, rel=1e-12)


def test_a_damper_loses_pi_c_omega_a_squared_per_cycle() -> None:
    c_per_deg = 0.05  # N·m per deg/s
    torque = np.array([viscous_torque_nm(c_per_deg, v) for v in SPEED])
    c_per_rad = c_per_deg * 180.0 / np.pi  # N·m per rad/s
    assert loop_energy_j(ANGLE, torque) == pytest.approx(np.pi * c_per_rad * OMEGA * A_RAD**2, rel=1e-6)


def test_a_bungee_pulls_only_on_its_taut_side() -> None:
    for direction, slack_side in ((1, np.linspace(-40.0, 20.0, 61)), (-1, np.linspace(20.0, 90.0, 71))):
        cord = build_element(
            "c", "bungee", {"stiffness_nm_per_deg": 0.8, "slack_deg": 20.0, "direction": direction}
        )
        np.testing.assert_array_equal(static_torque_nm(cord, slack_side), 0.0)
        taut = 20.0 + direction * 10.0
        assert static_torque_nm(cord, np.array([taut]))[0] == pytest.approx(direction * 8.0)


def test_a_mass_has_no_gravity_torque_where_it_hangs_and_mgl_when_horizontal() -> None:
    mass = build_element("m", "mass", {"mass_kg": 3.0, "lever_m": 0.2, "hanging_deg": 10.0})
    assert static_torque_nm(mass, np.array([10.0]))[0] == pytest.approx(0.0, abs=1e-12)
    assert static_torque_nm(mass, np.array([100.0]))[0] == pytest.approx(3.0 * 9.80665 * 0.2)


def test_the_lever_spring_has_no_torque_at_its_zero_torque_angle() -> None:
    """Eq 13: the spring line passes through the axis at alpha + zero offset (no lever arm)."""
    spring = build_element(*lever_spring(13.0, 3, zero_offset_deg=4.0))
    torque = static_torque_nm(spring, np.array([spring.number("alpha_deg") + 4.0, 60.0, 5.0]))
    assert torque[0] == pytest.approx(0.0, abs=1e-9)
    assert torque[1] > 0.0 > torque[2]  # resists bending both ways


def test_stops_push_back_towards_their_range_softly_then_stiffly() -> None:
    assert rom_stops_torque_nm(60.0, 40.0, 90.0, 13.0, 0.05, 40.0) == 0.0
    assert rom_stops_torque_nm(95.0, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(0.25)
    assert rom_stops_torque_nm(105.0, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(0.65 + 80.0)
    assert rom_stops_torque_nm(25.0, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(-(0.65 + 80.0))
