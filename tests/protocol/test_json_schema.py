"""The shipped JSON Schema: what an editor checks a campaign file against while it is typed."""

from __future__ import annotations

from pathlib import Path

import jsonschema
import pytest

from protocol_runner.protocol.schema import SCHEMA_FILE, protocol_json_schema, protocol_json_schema_text
from protocol_runner.protocol.yaml_doc import parse_yaml

REPO = Path(__file__).resolve().parents[2]
SHIPPED = sorted((REPO / "protocols").glob("*.yaml"))


def _data(path: Path) -> dict:
    data, _ = parse_yaml(path.read_text(encoding="utf-8"), path.name)  # read as `--validate` reads it
    return data


def _errors(data: dict) -> list[jsonschema.ValidationError]:
    return list(jsonschema.Draft202012Validator(protocol_json_schema()).iter_errors(data))


def test_the_shipped_schema_is_the_one_the_models_give() -> None:
    """The file an editor points at is what `--schema` prints; a field added to the models and not to the
    file would leave editors flagging a valid campaign."""
    assert SCHEMA_FILE.read_text(encoding="utf-8") == protocol_json_schema_text(), (
        f"regenerate it: `PYTHONPATH=src python -m protocol_runner --schema > {SCHEMA_FILE.relative_to(REPO)}`"
    )


def test_the_schema_is_a_valid_draft_2020_12_schema() -> None:
    jsonschema.Draft202012Validator.check_schema(protocol_json_schema())


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_every_shipped_protocol_is_valid_against_the_schema(path: Path) -> None:
    assert [e.message for e in _errors(_data(path))] == []


def test_an_unknown_key_is_rejected_where_it_stands() -> None:
    data = _data(REPO / "protocols" / "elbow_example.yaml")
    data["calibration_check"] = {**data["calibration_check"], "max_drfit_deg": 2.0}
    errors = _errors(data)
    assert len(errors) == 1
    assert list(errors[0].absolute_path) == ["calibration_check"]
    assert "'max_drfit_deg' was unexpected" in errors[0].message


def test_a_missing_required_key_and_a_value_out_of_bounds_are_rejected() -> None:
    data = _data(REPO / "protocols" / "elbow_example.yaml")
    del data["name"]
    data["processing"] = {**data["processing"], "filter": {**data["processing"]["filter"], "cutoff": 1.5}}
    messages = sorted(e.message for e in _errors(data))
    assert any("'name' is a required property" in m for m in messages), messages
    assert any("1.5 is greater than or equal to the maximum of 1" in m for m in messages), messages
