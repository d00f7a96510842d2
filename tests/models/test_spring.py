"""Facts about the reconstructed brace spring model (thesis §6.1, Eq 13-18)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import InvalidInput
from protocol_runner.models import spring
from protocol_runner.models.spring import SpringGeometry

from ..knee_device import KNEE_GEOMETRY as THESIS_GEOMETRY
from ..knee_device import KNEE_MAX_PRELOAD_MM as DEFAULT_MAX_PRELOAD_MM
from ..knee_device import STIFFNESS_N_PER_MM

# the knee brace's geometry and chosen Max_Preload (protocols/knee_phase1.yaml) unless a test says otherwise
KNEE = {"max_preload_mm": DEFAULT_MAX_PRELOAD_MM, "geometry": THESIS_GEOMETRY}


def spring_deflection_m(angle):  # type: ignore[no-untyped-def]
    """Eq 16 as the force shows it: F / K minus the initial load (a 1 N/mm spring with a positive preload)."""
    return spring_force_n(angle, 1.0, 1) / 1e3 - spring_initial_load_m(1)


def spring_initial_load_m(n, max_preload_mm=DEFAULT_MAX_PRELOAD_MM, geometry=THESIS_GEOMETRY):  # type: ignore[no-untyped-def]
    return spring.spring_initial_load_m(n, max_preload_mm, geometry)


def spring_force_n(angle, k, n, **kw):  # type: ignore[no-untyped-def]
    return spring.spring_force_n(angle, k, n, **{**KNEE, **kw})


def spring_torque_nm(angle, k, n, **kw):  # type: ignore[no-untyped-def]
    return spring.spring_torque_nm(angle, k, n, **{**KNEE, **kw})


FINE_GRID_DEG = np.linspace(0.0, 130.0, 13001)  # 0.01° steps
K2 = STIFFNESS_N_PER_MM["K2"]


def test_thesis_geometry_values() -> None:
    g = THESIS_GEOMETRY
    assert (g.a_m, g.b_m, g.c_m, g.alpha_deg, g.preload_step_deg, g.n_springs) == (
        0.03,
        0.19,
        0.055,
        20.0,
        2.73,
        2,
    )


def test_force_is_smallest_at_alpha() -> None:
    """Figure 50: the force is minimum when the brace angle equals alpha = 20°."""
    force = spring_force_n(FINE_GRID_DEG, K2, 3)
    assert FINE_GRID_DEG[np.argmin(force)] == pytest.approx(20.0, abs=0.02)


def test_deflection_zero_at_alpha_and_grows_on_both_sides() -> None:
    below = np.linspace(20.0, 0.0, 50)
    above = np.linspace(20.0, 130.0, 50)
    assert spring_deflection_m(20.0) == pytest.approx(0.0, abs=1e-12)
    assert np.all(np.diff(spring_deflection_m(below)) > 0)
    assert np.all(np.diff(spring_deflection_m(above)) > 0)


def test_deflection_matches_law_of_cosines() -> None:
    """The lower attachment is on a circle of radius a + b, the upper one at distance a: the triangle
    O-U-A has the angle theta - alpha at O."""
    g = THESIS_GEOMETRY
    theta = np.array([0.0, 45.0, 90.0, 130.0])
    r = g.a_m + g.b_m
    expected = np.sqrt(r**2 + g.a_m**2 - 2 * r * g.a_m * np.cos(np.radians(theta - g.alpha_deg))) - g.b_m
    np.testing.assert_allclose(spring_deflection_m(theta), expected, rtol=1e-12)


def test_torque_zero_at_alpha_and_sign_convention() -> None:
    """The spring line passes through the axis at alpha: no torque. Above it the brace resists flexion
    (positive torque per the sign convention), below it resists extension (negative)."""
    assert spring_torque_nm(20.0, K2, 3) == pytest.approx(0.0, abs=1e-9)
    assert np.all(spring_torque_nm(np.linspace(21.0, 130.0, 50), K2, 3) > 0)
    assert np.all(spring_torque_nm(np.linspace(0.0, 19.0, 20), K2, 3) < 0)


def test_torque_grows_with_bending_above_alpha() -> None:
    torque = spring_torque_nm(np.linspace(20.0, 120.0, 101), K2, 3)
    assert np.all(np.diff(torque) > 0)


def test_torque_equals_force_times_lever_arm() -> None:
    """Eq 13 with lambda from Eq 18 is the moment of the spring force: 2 F times the distance from the
    axis to the spring line, which is a r sin(theta - alpha) / L."""
    g = THESIS_GEOMETRY
    theta = np.array([5.0, 60.0, 100.0, 125.0])
    r = g.a_m + g.b_m
    length = spring_deflection_m(theta) + g.b_m
    arm = g.a_m * r * np.sin(np.radians(theta - g.alpha_deg)) / length
    expected = 2 * spring_force_n(theta, K2, 2) * arm
    np.testing.assert_allclose(spring_torque_nm(theta, K2, 2), expected, rtol=1e-10)


def test_torque_grows_with_stiffness() -> None:
    angle = np.array([60.0, 90.0, 110.0])
    k1, k2, k3 = (spring_torque_nm(angle, STIFFNESS_N_PER_MM[k], 3) for k in ("K1", "K2", "K3"))
    assert np.all(k1 < k2)
    assert np.all(k2 < k3)


def test_no_spring_gives_zero_torque() -> None:
    np.testing.assert_array_equal(spring_torque_nm(FINE_GRID_DEG, STIFFNESS_N_PER_MM["K0"], 3), 0.0)


def test_position_one_has_most_preload() -> None:
    loads = [spring_initial_load_m(n) for n in range(1, 6)]
    assert all(lo > hi for lo, hi in itertools.pairwise(loads))
    forces = np.array([spring_force_n(80.0, K2, n) for n in range(1, 6)])
    assert np.argmax(forces) == 0
    assert np.all(np.diff(forces) < 0)


def test_initial_load_is_eq17() -> None:
    g = THESIS_GEOMETRY
    expected = DEFAULT_MAX_PRELOAD_MM * 1e-3 - g.c_m * g.preload_step_deg * math.pi / 180 * 4
    assert spring_initial_load_m(4) == pytest.approx(expected, rel=1e-12)


def test_default_preload_positive_for_all_positions() -> None:
    assert all(spring_initial_load_m(n) > 0 for n in range(1, 6))


def test_default_preload_gives_tens_of_newton_metres_with_k2_near_110() -> None:
    """Design choice: K2 at centre preload supplies a large share of the 84.8 N·m limit near 110° but
    not all of it (gravity and friction add the rest, thesis §5.2)."""
    torque = spring_torque_nm(np.array([100.0, 110.0]), K2, 3)
    assert np.all(torque > 25.0)
    assert np.all(torque < 84.8)


def test_zero_offset_shifts_the_curve() -> None:
    angle = np.linspace(0.0, 130.0, 27)
    shifted = spring_torque_nm(angle, K2, 3, zero_offset_deg=5.0)
    np.testing.assert_allclose(shifted, spring_torque_nm(angle - 5.0, K2, 3), rtol=1e-12)
    assert spring_torque_nm(25.0, K2, 3, zero_offset_deg=5.0) == pytest.approx(0.0, abs=1e-9)


def test_vectorised_matches_scalar_calls() -> None:
    angle = np.array([[0.0, 33.0], [77.0, 129.0]])
    vector = spring_torque_nm(angle, 4.4, 5)
    assert vector.shape == (2, 2)
    for idx in np.ndindex(angle.shape):
        assert vector[idx] == pytest.approx(float(spring_torque_nm(float(angle[idx]), 4.4, 5)), rel=1e-12)


def test_slack_spring_pulls_with_zero_force() -> None:
    force = spring_force_n(np.array([20.0, 21.0]), K2, 5, max_preload_mm=0.0)
    np.testing.assert_array_equal(force, 0.0)


@pytest.mark.parametrize("position", [-1, 2.5, True, "3"])
def test_bad_preload_position_is_invalid_input(position: object) -> None:
    with pytest.raises(InvalidInput, match="preload position"):
        spring_torque_nm(30.0, K2, position)  # type: ignore[arg-type]


def test_negative_stiffness_is_invalid_input() -> None:
    with pytest.raises(InvalidInput, match="stiffness"):
        spring_force_n(30.0, -1.0, 3)


def test_bad_geometry_is_invalid_input() -> None:
    with pytest.raises(InvalidInput, match="a_m"):
        SpringGeometry(a_m=0.0, b_m=0.19, c_m=0.055, alpha_deg=20.0, preload_step_deg=2.73, n_springs=2)


@settings(max_examples=60)
@given(
    stiffness=st.floats(min_value=0.0, max_value=30.0),
    position=st.integers(min_value=1, max_value=5),
)
def test_torque_finite_over_the_knee_range(stiffness: float, position: int) -> None:
    torque = spring_torque_nm(np.linspace(0.0, 130.0, 131), stiffness, position)
    assert np.all(np.isfinite(torque))
