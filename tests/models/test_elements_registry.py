"""The element registry (models/elements.py): the contract the protocol loader checks campaign files against."""

from __future__ import annotations

import re

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.element_types import ELEMENT_TYPES
from protocol_runner.models.elements import build_device, build_element

UNIT_SUFFIXES = (
    "_deg_s2", "_deg_s", "_deg", "_rad", "_nm_s_per_deg", "_nm_per_deg", "_nm_per_rad", "_nm", "_n_per_mm",
    "_n_per_m", "_n", "_mm", "_m", "_kg", "_s", "_hz", "_j", "_v", "_turns", "_index", "_count", "_ratio",
    "_percent",
)  # fmt: skip


def test_every_parameter_name_carries_its_unit_suffix() -> None:
    for etype in ELEMENT_TYPES.values():
        for name, spec in etype.parameters.items():
            if spec.unit:
                assert spec.unit in UNIT_SUFFIXES, (etype.name, name)
                assert name.endswith(spec.unit) or name == spec.unit.lstrip("_"), (etype.name, name)
                # the longest known suffix of the name is the declared one (no "_deg" for a "_deg_s" name)
                longest = max((s for s in UNIT_SUFFIXES if name.endswith(s)), key=len, default=spec.unit)
                assert longest == spec.unit, (etype.name, name)
            assert spec.doc, (etype.name, name)


def test_the_issue_types_and_their_contract_parameters_exist() -> None:
    expected = {
        "lever_spring": {"stiffness_n_per_mm", "preload_index", "max_preload_mm", "zero_offset_deg", "count"},
        "torsion_spring": {"stiffness_nm_per_deg", "neutral_deg"},
        "bungee": {"stiffness_nm_per_deg", "slack_deg", "direction"},
        "coulomb_brake": {"torque_nm", "transition_deg", "static_excess_ratio", "stribeck_speed_deg_s"},
        "viscous_damper": {"damping_nm_s_per_deg"},
        "rom_stops": {"range_deg", "slack_deg", "slack_stiffness_nm_per_deg", "stop_stiffness_nm_per_deg"},
        "mass": {"mass_kg", "lever_m", "hanging_deg"},
        "cuff_shift": {"angle_deg", "width_deg", "torque_nm", "reference_speed_deg_s", "reference_force_n"},
    }
    assert set(ELEMENT_TYPES) == set(expected)
    for name, params in expected.items():
        assert params <= set(ELEMENT_TYPES[name].parameters), name


def test_only_elastic_elements_have_a_fit_and_its_defaults_are_fittable() -> None:
    for etype in ELEMENT_TYPES.values():
        fittable = {k for k, s in etype.parameters.items() if s.fittable}
        assert set(etype.default_fit) <= fittable
        assert ("fit" in etype.parameters) == (etype.kind == "elastic")
        assert bool(fittable) == (etype.kind == "elastic")


def test_defaults_are_filled_and_values_checked() -> None:
    e = build_element("cord", "bungee", {"stiffness_nm_per_deg": 0.5, "slack_deg": 10})
    assert e.params["direction"] == 1.0 and e.fit == ("stiffness_nm_per_deg", "slack_deg")
    assert build_element(
        "cord", "bungee", {"stiffness_nm_per_deg": 0.5, "slack_deg": 10, "fit": "slack_deg"}
    ).fit == ("slack_deg",)
    stops = build_element("s", "rom_stops", {"range_deg": [40, 90], "stop_stiffness_nm_per_deg": 40})
    assert stops.pair("range_deg") == (40.0, 90.0)


@pytest.mark.parametrize(
    ("type_", "params", "named"),
    [
        ("spring", {}, "unknown element type 'spring'"),
        ("bungee", {"stiffness_nm_per_deg": 1.0}, "'slack_deg' is required"),
        ("bungee", {"stiffness_nm_per_deg": 1.0, "slack_deg": 0, "colour": 1}, "'colour' is unknown"),
        ("bungee", {"stiffness_nm_per_deg": 1.0, "slack_deg": 0, "direction": 2}, "'direction' must be +1 or -1"),
        ("bungee", {"stiffness_nm_per_deg": -1.0, "slack_deg": 0}, "'stiffness_nm_per_deg' must lie in"),
        ("bungee", {"stiffness_nm_per_deg": "soft", "slack_deg": 0}, "'stiffness_nm_per_deg' must be a number"),
        ("rom_stops", {"range_deg": [90, 40], "stop_stiffness_nm_per_deg": 1}, "'range_deg' must be [lo, hi]"),
        ("coulomb_brake", {"torque_nm": True}, "'torque_nm' must be a number"),
        ("torsion_spring", {"stiffness_nm_per_deg": 1, "neutral_deg": 0, "fit": ["x"]}, "'x' is not a fittable"),
        ("lever_spring", {"stiffness_n_per_mm": 1, "max_preload_mm": 1, "a_m": 1, "b_m": 1, "alpha_deg": 0,
                          "count": 1.5}, "'count' must be a whole number"),
    ],
)  # fmt: skip
def test_bad_parameters_are_refused_naming_the_element_and_the_parameter(
    type_: str, params: dict[str, object], named: str
) -> None:
    with pytest.raises(InvalidInput, match=re.escape(named)) as err:
        build_element("e1", type_, params)
    assert "'e1'" in err.value.message


def test_a_device_accepts_settings_objects_and_tuples_and_refuses_duplicate_names() -> None:
    class Setting:
        name, type, params = "damper", "viscous_damper", (("damping_nm_s_per_deg", 0.1),)

    device = build_device([Setting(), ("brake", "coulomb_brake", {"torque_nm": 2.0})])
    assert [e.name for e in device] == ["damper", "brake"]
    assert device[0].kind == "dissipative" and device[1].params["transition_deg"] == 1.0
    with pytest.raises(InvalidInput, match="two elements"):
        build_device([Setting(), Setting()])
