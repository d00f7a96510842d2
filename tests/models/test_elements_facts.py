"""Facts of a device's elements (models/elements.py): an element is an immutable value (hashable, equal
by content), its JSON form carries every resolved parameter, and each parameter shape admits exactly its
values (a pair of two numbers, a whole number, a sign of either direction)."""

from __future__ import annotations

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.elements import build_element

STOPS = {"range_deg": [-10.0, 95.0], "stop_stiffness_nm_per_deg": 2.0}


def test_an_element_is_a_hashable_value() -> None:
    a = build_element("stops", "rom_stops", STOPS)
    b = build_element("stops", "rom_stops", dict(STOPS))
    assert a == b and hash(a) == hash(b)
    assert len({a, b}) == 1


def test_the_json_form_carries_every_resolved_parameter_with_pairs_as_lists() -> None:
    e = build_element("stops", "rom_stops", STOPS)
    assert e.to_json() == {
        "name": "stops",
        "type": "rom_stops",
        "range_deg": [-10.0, 95.0],
        "slack_deg": 0.0,
        "slack_stiffness_nm_per_deg": 0.0,
        "stop_stiffness_nm_per_deg": 2.0,
    }


@pytest.mark.parametrize("value", [[1.0, 2.0, 3.0], [1.0], 5.0])
def test_a_pair_is_exactly_two_numbers(value: object) -> None:
    with pytest.raises(InvalidInput, match="must be a pair"):
        build_element("stops", "rom_stops", {**STOPS, "range_deg": value})


@pytest.mark.parametrize("index", [2.3, 2.7, -0.5])
def test_an_integer_parameter_refuses_any_fraction(index: float) -> None:
    spring = {"stiffness_n_per_mm": 1.0, "max_preload_mm": 10.0, "a_m": 0.1, "b_m": 0.1, "alpha_deg": 0.0}
    assert build_element("s", "lever_spring", {**spring, "preload_index": 3}).number("preload_index") == 3.0
    with pytest.raises(InvalidInput, match="whole number"):
        build_element("s", "lever_spring", {**spring, "preload_index": index})


def test_a_sign_is_either_direction_and_nothing_else() -> None:
    cord = {"stiffness_nm_per_deg": 1.0, "slack_deg": 20.0}
    for direction in (1, -1):
        assert build_element("c", "bungee", {**cord, "direction": direction}).number("direction") == direction
    for bad in (0, 2, -0.5):
        with pytest.raises(InvalidInput, match="must be \\+1 or -1"):
            build_element("c", "bungee", {**cord, "direction": bad})


SPRING = {
    "stiffness_n_per_mm": 2.0,
    "preload_index": 3.0,
    "max_preload_mm": 20.0,
    "a_m": 0.05,
    "b_m": 0.1,
    "alpha_deg": 30.0,
    "fit": ["max_preload_mm"],
}


def test_replace_is_build_element_with_the_new_values() -> None:
    """`replace` (the element fit's trial points) checks only the changed values, and gives exactly the
    element `build_element` gives for the same parameters."""
    e = build_element("springs", "lever_spring", SPRING)
    changed = e.replace(max_preload_mm=25, zero_offset_deg=-2.5)
    assert changed == build_element(
        "springs", "lever_spring", {**SPRING, "max_preload_mm": 25.0, "zero_offset_deg": -2.5}
    )
    assert changed.number("max_preload_mm") == 25.0 and isinstance(changed.params["max_preload_mm"], float)
    assert list(changed.params) == list(e.params)  # the parameters in their declared order
    assert e.number("max_preload_mm") == 20.0  # the original is unchanged


def test_replace_refuses_what_build_element_refuses() -> None:
    e = build_element("springs", "lever_spring", SPRING)
    with pytest.raises(InvalidInput, match="'stiffness_n_per_mm' must lie in"):
        e.replace(stiffness_n_per_mm=-1.0)
    with pytest.raises(InvalidInput, match="must be finite"):
        e.replace(max_preload_mm=float("nan"))
    with pytest.raises(InvalidInput, match="'no_such' is unknown"):
        e.replace(no_such=1.0)
