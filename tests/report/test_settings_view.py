"""The report's reader of declared settings: what the archive writer stores (spec: docs/archive.md
"Configurations") reads back unchanged, units come from quantity-name suffixes, bad JSON is named."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.settings import (
    ElementSetting,
    FactorSetting,
    Settings,
    configuration_attributes,
)
from protocol_runner.protocol.units import unit_suffix
from protocol_runner.report.settings_view import (
    axis_label,
    format_quantity,
    quantity_title,
    settings_from_attrs,
    unit_label,
)

# an invented campaign: nothing here is a knee name, and the reader must not care
SETTINGS = Settings(
    factors=(
        ("damper", FactorSetting("soft", (("damping_nm_s_per_deg", 0.02),))),
        ("stops", FactorSetting("wide", (("range_deg", (-40.0, 25.0)), ("slack_deg", 3.0)))),
        ("pace", FactorSetting("slow", (("speed_deg_s", 15.0),))),
    ),
    device=(
        ElementSetting("visc", "viscous_damper", (("damping_nm_s_per_deg", 0.02),)),
        ElementSetting("ends", "rom_stops", (("range_deg", (-40.0, 25.0)), ("slack_deg", 3.0))),
    ),
)


def _written(tmp_path: Path, settings: Settings) -> dict[str, object]:
    """The attributes as an HDF5 configuration group holds them (numpy types, string arrays)."""
    with h5py.File(tmp_path / "a.h5", "w") as f:
        g = f.create_group("configurations/config_01")
        for key, value in configuration_attributes(settings).items():
            g.attrs[key] = value
        g.attrs["trajectory_name"] = "tri"
        return dict(g.attrs.items())


def test_what_the_archive_writer_stores_reads_back_in_declaration_order(tmp_path: Path) -> None:
    view = settings_from_attrs(_written(tmp_path, SETTINGS), "config_01")
    assert view.factor_names() == ("damper", "stops", "pace")
    assert view.level("stops") == "wide"
    assert view.quantity("stops", "range_deg") == (-40.0, 25.0)
    assert view.quantity("pace", "speed_deg_s") == 15.0
    assert view.quantity("pace", "range_deg") is None and view.level("missing") is None
    assert view.trajectory == "tri"
    assert [(e.name, e.type) for e in view.device] == [("visc", "viscous_damper"), ("ends", "rom_stops")]
    ends = view.element("ends")
    assert ends is not None and dict(ends.params)["range_deg"] == (-40.0, 25.0)
    # the flattened form equals the writer's flattened attributes, key for key
    attrs = configuration_attributes(SETTINGS)
    flat = {k: v for k, v in attrs.items() if k not in ("factors", "settings_json", "device_json")}
    assert {k: (list(v) if isinstance(v, tuple) else v) for k, v in view.flat().items()} == flat


def test_an_archive_without_declared_settings_gives_empty_settings() -> None:
    view = settings_from_attrs({"key": 3, "profile": "sinusoid"}, "config_03")
    assert view.factors == () and view.device == () and view.flat() == {}


@pytest.mark.parametrize(
    ("attrs", "message"),
    [
        ({"settings_json": "{not json"}, "settings_json is not valid JSON"),
        ({"settings_json": "[1, 2]"}, "settings_json must be a JSON object"),
        (
            {"settings_json": json.dumps({"pace": {"speed_deg_s": 3}})},
            r"settings_json.pace must be .* 'level'",
        ),
        ({"settings_json": json.dumps({"pace": {"level": "a", "speed_deg_s": "x"}})}, "pace.speed_deg_s"),
        ({"device_json": json.dumps([{"name": "a"}])}, r"device_json\[0\] must be an object"),
    ],
)
def test_malformed_settings_are_named(attrs: dict[str, object], message: str) -> None:
    with pytest.raises(InvalidInput, match=message) as err:
        settings_from_attrs(attrs, "archive.h5: config_07")
    assert "config_07" in str(err.value)


def test_units_come_from_the_longest_matching_suffix() -> None:
    assert unit_suffix("damping_nm_s_per_deg") == "_nm_s_per_deg"
    assert unit_suffix("stop_stiffness_nm_per_deg") == "_nm_per_deg"
    assert unit_suffix("max_accel_deg_s2") == "_deg_s2"
    assert unit_suffix("speed_deg_s") == "_deg_s"
    assert unit_suffix("range_deg") == "_deg"
    assert unit_suffix("deg") is None  # a bare unit word names no quantity
    assert unit_label("friction_nm") == "N·m"
    assert unit_label("stiffness_n_per_mm") == "N/mm"
    assert unit_label("preload_index") == ""
    assert unit_label("colour") == ""


def test_quantities_print_with_their_units() -> None:
    assert format_quantity("torque_nm", 3.75) == "3.75 N·m"
    assert format_quantity("range_deg", (40.0, 90.0)) == "40–90 deg"
    assert format_quantity("offsets_mm", (1.0, 2.0, 3.0)) == "1, 2, 3 mm"
    assert format_quantity("position_index", 3.0) == "3"
    assert format_quantity("share_percent", 25.0) == "25%"
    assert quantity_title("screw_turns") == "screw"
    assert axis_label("pace", "speed_deg_s") == "pace: speed (deg/s)"


def test_element_parameters_keep_words_and_lists_of_words() -> None:
    text = json.dumps(
        [{"name": "s", "type": "lever_spring", "k_n_per_mm": 4, "fit": ["zero_offset_deg"], "side": "left"}]
    )
    view = settings_from_attrs({"device_json": text}, "config_01")
    (element,) = view.device
    assert element.params == (("k_n_per_mm", 4.0), ("fit", ("zero_offset_deg",)), ("side", "left"))
