"""A brace geometry with no springs fitted is valid and has no spring torque."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.spring import SpringGeometry, spring_torque_nm


def test_zero_springs_is_a_valid_geometry_with_no_torque() -> None:
    dims = {"a_m": 0.03, "b_m": 0.19, "c_m": 0.055, "alpha_deg": 20.0, "preload_step_deg": 2.73}
    bare = SpringGeometry(**dims, n_springs=0)
    torque = spring_torque_nm(np.linspace(0.0, 130.0, 14), 13.0, 3, max_preload_mm=32.0, geometry=bare)
    np.testing.assert_array_equal(torque, 0.0)
    with pytest.raises(InvalidInput, match="n_springs"):
        SpringGeometry(**dims, n_springs=-1)


GEOMETRY = {
    "a_m": 0.03,
    "b_m": 0.19,
    "c_m": 0.055,
    "alpha_deg": 20.0,
    "preload_step_deg": 2.73,
    "n_springs": 2,
}


def test_a_brace_without_a_preload_piece_has_no_preload_step() -> None:
    """c = 0 (no preload lever, Eq 17): a valid geometry whose screw positions all give Max_Preload; the
    two attachment distances a and b must be positive lengths."""
    geometry = SpringGeometry(**{**GEOMETRY, "c_m": 0.0})
    assert geometry.preload_step_m == 0.0
    for name in ("a_m", "b_m"):
        with pytest.raises(InvalidInput, match=f"{name} must be a positive length"):
            SpringGeometry(**{**GEOMETRY, name: 0.0})
    with pytest.raises(InvalidInput, match="c_m must be a positive length"):
        SpringGeometry(**{**GEOMETRY, "c_m": -0.01})


@pytest.mark.parametrize("name", ["alpha_deg", "preload_step_deg"])
@pytest.mark.parametrize("value", [float("inf"), float("nan")])
def test_each_angle_of_the_geometry_must_be_finite_on_its_own(name: str, value: float) -> None:
    with pytest.raises(InvalidInput, match="alpha_deg and preload_step_deg must be finite"):
        SpringGeometry(**{**GEOMETRY, name: value})
