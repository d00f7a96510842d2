"""The protocol file's JSON Schema, for editors: completion and checking while a campaign is typed.

The schema is generated from the same pydantic models that validate a protocol (`schema.Protocol`), so it
cannot drift from what `--validate` accepts field by field; it rejects unknown keys as `--validate` does.
What it cannot express - cross-field checks such as a level naming a declared factor, a trajectory inside
the joint's range, the rig's rate limits - is left to `run-protocol --validate`, which an editor cannot run.

A copy ships in the package (`protocol_runner/schemas/protocol.schema.json`) so that an editor can point
at a file; `run-protocol --schema` prints the same text.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .schema import Protocol

SCHEMA_FILE = Path(__file__).resolve().parent.parent / "schemas" / "protocol.schema.json"
"""The schema as shipped with the package."""


def protocol_json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a protocol file."""
    schema = Protocol.model_json_schema()
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "protocol-runner campaign file",
        **{k: v for k, v in schema.items() if k != "title"},
    }


def protocol_json_schema_text() -> str:
    """The schema as the text shipped and printed (sorted keys, two-space indent, a final newline)."""
    return json.dumps(protocol_json_schema(), indent=2, sort_keys=True, ensure_ascii=False) + "\n"
