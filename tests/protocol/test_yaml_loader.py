"""Protocol and rig files are read by libyaml when PyYAML has it (issue 20: the pure-Python reader took most
of a second of the start-up); what is read, the line of every key, and every message about a bad file are
exactly those of the pure-Python loader."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol import yaml_doc
from protocol_runner.resources import packaged_rigs_dir

REPO = Path(__file__).resolve().parents[2]
KNEE_TEXT = (REPO / "protocols" / "knee_phase1.yaml").read_text(encoding="utf-8")
RIG_TEXT = (packaged_rigs_dir() / "rsst.yaml").read_text(encoding="utf-8")

needs_libyaml = pytest.mark.skipif(yaml_doc.FAST_LOADER is None, reason="PyYAML built without libyaml")

BAD = {
    "tab indent": KNEE_TEXT.replace("\nname:", "\n\tname:", 1),
    "unclosed flow": KNEE_TEXT.replace("{key: 11,", "{key: 11, [", 1),
    "bad indent": KNEE_TEXT.replace("\nname:", "\n  oops: 1\n name:", 1),
    "unclosed quote": KNEE_TEXT + '\nextra: "never closed\n',
    "control character": KNEE_TEXT.replace("\nname:", "\nna\x07me:", 1),
    "undefined alias": KNEE_TEXT + "\nextra: *nowhere\n",
    "too deep": "a: " + "[" * 60 + "]" * 60 + "\n",
    "billion laughs": "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n"
    + "".join(f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(7)),
    "duplicate key": KNEE_TEXT.replace("name: knee_phase1\n", "name: knee_phase1\nname: again\n", 1),
}


def pure_python(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(yaml_doc, "FAST_LOADER", None)


def message(text: str) -> str:
    with pytest.raises(InvalidInput) as info:
        yaml_doc.parse_yaml(text, "p.yaml")
    return info.value.message


@needs_libyaml
@pytest.mark.parametrize("text", [KNEE_TEXT, RIG_TEXT], ids=["knee protocol", "rsst rig"])
def test_libyaml_reads_the_same_data_and_lines_in_one_pass(
    text: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    loaders: list[Any] = []
    inner = yaml_doc._compose_and_construct

    def spy(t: str, loader_class: Any) -> Any:
        loaders.append(loader_class)
        return inner(t, loader_class)

    monkeypatch.setattr(yaml_doc, "_compose_and_construct", spy)
    fast = yaml_doc.parse_yaml(text, "p.yaml")
    assert loaders == [yaml.CSafeLoader]  # one composition, and not the pure-Python one
    pure_python(monkeypatch)
    slow = yaml_doc.parse_yaml(text, "p.yaml")
    assert loaders == [yaml.CSafeLoader, yaml.SafeLoader]
    assert fast == slow and fast[0] == yaml.safe_load(text) and len(fast[1]) > 100


@pytest.mark.parametrize("name", list(BAD))
def test_a_bad_file_gets_the_pure_python_loaders_located_message(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    shown = message(BAD[name])
    assert shown.startswith("p.yaml:") and shown.split(":")[1].isdigit(), shown
    pure_python(monkeypatch)
    assert message(BAD[name]) == shown
