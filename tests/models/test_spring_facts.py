"""A brace geometry with no springs fitted is valid and has no spring torque."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.spring import SpringGeometry, spring_torque_nm


def test_zero_springs_is_a_valid_geometry_with_no_torque() -> None:
    bare = SpringGeometry(n_springs=0)
    np.testing.assert_array_equal(spring_torque_nm(np.linspace(0.0, 130.0, 14), 13.0, 3, geometry=bare), 0.0)
    with pytest.raises(InvalidInput, match="n_springs"):
        SpringGeometry(n_springs=-1)
