"""A quantity's unit is one suffix of the table, exactly (docs/protocol.md "Factors and quantities")."""

from __future__ import annotations

import pytest

from protocol_runner.protocol.units import compound_unit_problem, unit_suffix


@pytest.mark.parametrize(
    "name",
    [
        "speed_deg_s",
        "range_deg",
        "friction_nm",
        "stiffness_n_per_mm",
        "damping_nm_s_per_deg",
        "damping_nm_s_per_rad",
        "position_index",
        "screw_turns",
        "hold_s",
        "max_accel_deg_s2",
        "lever_m",
    ],
)
def test_a_name_ending_with_one_unit_of_the_table_is_a_quantity(name: str) -> None:
    assert unit_suffix(name) is not None and compound_unit_problem(name) is None


@pytest.mark.parametrize(
    ("name", "reads_as", "unit"),
    [
        ("speed_rad_s", "_s", "_rad_s"),
        ("torque_n_m", "_m", "_n_m"),
        ("stiffness_nm_per_m", "_m", "_nm_per_m"),
        ("rate_deg_per_s", "_s", "_deg_per_s"),
    ],
)
def test_a_compound_unit_not_in_the_table_is_refused_not_read_as_its_last_part(
    name: str, reads_as: str, unit: str
) -> None:
    assert unit_suffix(name) == reads_as  # what the name would silently mean
    problem = compound_unit_problem(name)
    assert problem is not None and f"the unit {unit} is not one of the unit suffixes" in problem
