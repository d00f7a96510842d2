"""The Settings contract (protocol/settings.py): plan JSON and archive attributes of one configuration."""

from __future__ import annotations

import json

from protocol_runner.protocol.settings import (
    ElementSetting,
    FactorSetting,
    Settings,
    configuration_attributes,
)

SETTINGS = Settings(
    factors=(
        ("stops", FactorSetting(level="wide", quantities=(("range_deg", (-40.0, 25.0)),))),
        ("brake", FactorSetting(level="b2", quantities=(("friction_nm", 3.75), ("screw_turns", 0.75)))),
    ),
    device=(
        ElementSetting("brake", "coulomb_brake", (("torque_nm", 3.75), ("transition_deg", 2.0))),
        ElementSetting("stops", "rom_stops", (("range_deg", (-40.0, 25.0)),)),
    ),
)


def test_plan_settings_are_one_entry_per_factor_with_level_and_quantities() -> None:
    assert SETTINGS.to_json() == {
        "stops": {"level": "wide", "range_deg": [-40.0, 25.0]},
        "brake": {"level": "b2", "friction_nm": 3.75, "screw_turns": 0.75},
    }
    assert list(SETTINGS.to_json()) == ["stops", "brake"]  # declaration order
    assert SETTINGS.level("brake") == "b2" and SETTINGS.level("speed") is None
    assert SETTINGS.quantity("stops", "range_deg") == (-40.0, 25.0)
    assert SETTINGS.quantity("brake", "stiffness_n_per_mm") is None


def test_device_json_lists_elements_in_order_with_their_parameters() -> None:
    assert SETTINGS.device_json() == [
        {"name": "brake", "type": "coulomb_brake", "torque_nm": 3.75, "transition_deg": 2.0},
        {"name": "stops", "type": "rom_stops", "range_deg": [-40.0, 25.0]},
    ]


def test_archive_attributes_flatten_each_factor_and_nothing_else() -> None:
    attrs = configuration_attributes(SETTINGS)
    assert set(attrs) == {
        "factors",
        "settings_json",
        "device_json",
        "stops",
        "stops.range_deg",
        "brake",
        "brake.friction_nm",
        "brake.screw_turns",
    }
    assert attrs["factors"] == ["stops", "brake"]
    assert json.loads(attrs["settings_json"]) == SETTINGS.to_json()
    assert json.loads(attrs["device_json"]) == SETTINGS.device_json()
    assert attrs["stops"] == "wide" and attrs["stops.range_deg"] == [-40.0, 25.0]
    assert attrs["brake.friction_nm"] == 3.75
