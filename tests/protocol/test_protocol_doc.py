"""docs/protocol.md is the language's complete reference: every element type and
parameter, trajectory kind, unit suffix, generator and top-level key is documented there."""

from __future__ import annotations

from pathlib import Path

from protocol_runner.models.element_types import ELEMENT_TYPES
from protocol_runner.protocol.schema import Protocol, SetSpec
from protocol_runner.protocol.trajectory_specs import kind_names
from protocol_runner.protocol.units import UNIT_SUFFIXES

DOC = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text(encoding="utf-8")


def test_every_element_type_and_parameter_is_documented_with_an_example() -> None:
    for name, etype in ELEMENT_TYPES.items():
        assert f"### `{name}`" in DOC, name
        assert f"type: {name}" in DOC, f"no example of {name}"
        for param in etype.parameters:
            assert f"`{param}`" in DOC, f"{name}.{param}"


def test_every_trajectory_kind_unit_suffix_and_generator_is_documented() -> None:
    for kind in kind_names():
        assert f"kind: {kind}" in DOC, kind
    for suffix in UNIT_SUFFIXES:
        assert f"`{suffix}`" in DOC, suffix
    for generator in ("full_factorial", "one_factor_at_a_time"):
        assert f"{generator}:" in DOC and generator in SetSpec.model_fields


def test_every_top_level_key_is_in_the_table() -> None:
    for name, info in Protocol.model_fields.items():
        assert f"| `{info.alias or name}` |" in DOC, name
