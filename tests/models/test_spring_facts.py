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
