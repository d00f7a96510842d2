"""Each device element's torque equation (models/element_torques.py) against a physical fact."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.models.element_torques import (
    cuff_shift_height_nm,
    cuff_shift_torque_nm,
    dahl_update,
    has_static_torque,
    lever_spring_force_n,
    rom_stops_torque_nm,
    static_torque_nm,
    stribeck_level_nm,
    viscous_torque_nm,
)
from protocol_runner.models.element_types import ELEMENT_TYPES
from protocol_runner.models.elements import build_element

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
CUFF_SHIFT_PARAMS = {
    "angle_deg": 35.0,
    "width_deg": 5.0,
    "torque_nm": 4.0,
    "reference_speed_deg_s": 50.0,
    "reference_force_n": 200.0,
}


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


def test_the_lever_springs_tension_is_the_screw_preload_alone_at_its_zero_torque_angle() -> None:
    """Eq 14 and 17: at alpha + zero offset the spring has its undeflected length b, so its tension is
    K * Initial_Load = K * (Max_Preload - c * step * pi/180 * n) (knee: 13 N/mm, 32 mm, 55 mm, 2.73 deg,
    n = 3); on either side of that angle it stretches and pulls harder."""
    spring = build_element(*lever_spring(13.0, 3, zero_offset_deg=6.0))
    zero_deg = spring.number("alpha_deg") + 6.0
    initial_load_mm = 32.0 - 55.0 * np.radians(2.73) * 3
    assert lever_spring_force_n(zero_deg, spring) == pytest.approx(13.0 * initial_load_mm, rel=1e-12)
    assert lever_spring_force_n(zero_deg - 10.0, spring) > 13.0 * initial_load_mm
    assert lever_spring_force_n(zero_deg + 10.0, spring) > 13.0 * initial_load_mm


def test_the_lever_springs_torque_is_the_tension_times_its_lever_arm() -> None:
    """Eq 13 in the reconstructed geometry: T = n_springs * F * a * r * sin(theta - alpha) / L, with F the
    tension of one spring (Eq 14), r = a + b and L the spring's length at the brace angle theta."""
    offset = -3.0
    spring = build_element(*lever_spring(13.0, 2, zero_offset_deg=offset))
    a, b, alpha = spring.number("a_m"), spring.number("b_m"), np.radians(spring.number("alpha_deg"))
    r = a + b
    for angle in (-10.0, 5.0, 60.0, 110.0):
        theta = np.radians(angle - offset)
        length = np.sqrt(r * r + a * a - 2.0 * a * r * np.cos(theta - alpha))
        force = lever_spring_force_n(angle, spring)
        expected = spring.number("count") * force * a * r * np.sin(theta - alpha) / length
        assert static_torque_nm(spring, np.array([angle]))[0] == pytest.approx(expected, rel=1e-9)


def test_a_torsion_spring_is_linear_about_its_neutral_angle() -> None:
    spring = build_element("t", "torsion_spring", {"stiffness_nm_per_deg": 0.4, "neutral_deg": 35.0})
    np.testing.assert_allclose(static_torque_nm(spring, np.array([35.0, 45.0, 25.0])), [0.0, 4.0, -4.0])


@pytest.mark.parametrize(
    "element",
    [
        ("brake", "coulomb_brake", {"torque_nm": 2.0}),
        ("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.1}),
        ("stops", "rom_stops", {"range_deg": [0, 90], "stop_stiffness_nm_per_deg": 5.0}),
        ("cuff", "cuff_shift", CUFF_SHIFT_PARAMS),
    ],
    ids=lambda e: e[1],
)
def test_elements_whose_torque_needs_more_than_the_angle_have_no_static_torque(element: tuple) -> None:
    built = build_element(*element)
    assert not has_static_torque(built)
    with pytest.raises(ValueError, match=f"element '{element[0]}' \\({element[1]}\\) has no angle-only"):
        static_torque_nm(built, np.array([10.0]))


def test_a_brake_without_friction_holds_no_torque() -> None:
    assert dahl_update(1.5, 0.0, 2.0, 1.0) == 0.0
    assert dahl_update(-1.5, 0.0, -2.0, 1.0) == 0.0


def test_the_dahl_state_relaxes_exponentially_with_travel_and_holds_at_standstill() -> None:
    """dz/dx = (target - z) / transition: from z = 0, one transition of travel reaches level (1 - 1/e); the
    update is exact, so two half steps give the same state as one step; at standstill z is kept; moving
    the other way the target is -level."""
    level, transition = 3.0, 2.0
    assert dahl_update(0.0, level, transition, transition) == pytest.approx(level * (1.0 - np.exp(-1.0)))
    half = dahl_update(dahl_update(0.5, level, 0.7, transition), level, 0.7, transition)
    assert half == pytest.approx(dahl_update(0.5, level, 1.4, transition), rel=1e-12)
    assert dahl_update(1.2, level, 0.0, transition) == 1.2
    assert dahl_update(0.0, level, -transition, transition) == pytest.approx(-level * (1.0 - np.exp(-1.0)))
    assert dahl_update(level, level, -1e6, transition) == pytest.approx(-level)


def test_the_stribeck_excess_falls_to_one_over_e_at_the_stribeck_speed_either_way() -> None:
    for speed in (20.0, -20.0):
        assert stribeck_level_nm(2.0, speed, 0.3, 20.0) == pytest.approx(2.0 * (1.0 + 0.3 / np.e))


def test_a_stop_is_continuous_where_its_slack_ends() -> None:
    """At exactly the slack's end both pieces give slack_k * slack; on the low side the push is upward."""
    assert rom_stops_torque_nm(90.0, 40.0, 90.0, 13.0, 0.05, 40.0) == 0.0
    assert rom_stops_torque_nm(40.0, 40.0, 90.0, 13.0, 0.05, 40.0) == 0.0
    assert rom_stops_torque_nm(103.0, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(0.65)
    assert rom_stops_torque_nm(103.0 + 1e-9, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(0.65)
    assert rom_stops_torque_nm(35.0, 40.0, 90.0, 13.0, 0.05, 40.0) == pytest.approx(-0.25)


def test_the_cuff_shift_is_a_gaussian_bump_growing_with_speed_up_to_three_times() -> None:
    """height * min(|v| / v_ref, 3) * exp(-((angle - centre) / width)^2), the same sign on both branches."""
    bump = (35.0, 5.0, 4.0, 50.0)  # centre, width, height, reference speed
    assert cuff_shift_torque_nm(35.0, 50.0, *bump) == pytest.approx(4.0)
    assert cuff_shift_torque_nm(35.0, -50.0, *bump) == pytest.approx(4.0)
    assert cuff_shift_torque_nm(40.0, 25.0, *bump) == pytest.approx(2.0 / np.e)
    assert cuff_shift_torque_nm(30.0, -25.0, *bump) == pytest.approx(2.0 / np.e)
    assert cuff_shift_torque_nm(35.0, 1000.0, *bump) == pytest.approx(12.0)
    assert cuff_shift_torque_nm(37.5, 50.0, *bump) == pytest.approx(4.0 * np.exp(-0.25))
    assert cuff_shift_torque_nm(31.0, 50.0, *bump) == pytest.approx(4.0 * np.exp(-0.64))
    assert cuff_shift_torque_nm(35.0, 0.0, *bump) == 0.0
    assert cuff_shift_torque_nm(35.0 + 5.0 * 3.0, 50.0, *bump) == pytest.approx(4.0 * np.exp(-9.0))
    assert cuff_shift_torque_nm(35.0 + 5.0 * 10.0, 50.0, *bump) == pytest.approx(0.0, abs=1e-40)


def test_a_spring_force_equal_to_the_reference_force_halves_the_cuff_shift() -> None:
    """height = torque * F_ref / (F_ref + the lever springs' force at the bump's angle); no springs: the
    full torque; a reference force of 0: no bump at all."""
    spring = build_element(*lever_spring(13.0, 3))
    force = lever_spring_force_n(CUFF_SHIFT_PARAMS["angle_deg"], spring)
    cuff = build_element("cuff", "cuff_shift", {**CUFF_SHIFT_PARAMS, "reference_force_n": force})
    assert cuff_shift_height_nm(cuff, [spring]) == pytest.approx(2.0, rel=1e-12)
    assert cuff_shift_height_nm(cuff, [spring, spring]) == pytest.approx(4.0 / 3.0, rel=1e-12)
    assert cuff_shift_height_nm(cuff, []) == pytest.approx(4.0, rel=1e-12)
    slack = build_element(*lever_spring(0.0, 3))
    assert cuff_shift_height_nm(cuff, [slack]) == pytest.approx(4.0, rel=1e-12)
    off = build_element("cuff", "cuff_shift", {**CUFF_SHIFT_PARAMS, "reference_force_n": 0.0})
    assert cuff_shift_height_nm(off, [spring]) == 0.0
