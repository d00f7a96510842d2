"""Protocol and rig files are read by libyaml when PyYAML has it (the pure-Python reader took most
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
    libyaml = yaml_doc.FAST_LOADER
    assert issubclass(libyaml, yaml.CSafeLoader)
    fast = yaml_doc.parse_yaml(text, "p.yaml")
    assert loaders == [libyaml]  # one composition, and not the pure-Python one
    pure_python(monkeypatch)
    slow = yaml_doc.parse_yaml(text, "p.yaml")
    assert loaders == [libyaml, yaml_doc.SafeLoader]
    assert fast == slow and fast[0] == yaml.safe_load(text) and len(fast[1]) > 100


@pytest.mark.parametrize("name", list(BAD))
def test_a_bad_file_gets_the_pure_python_loaders_located_message(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    shown = message(BAD[name])
    assert shown.startswith("p.yaml:") and shown.split(":")[1].isdigit(), shown
    pure_python(monkeypatch)
    assert message(BAD[name]) == shown


def test_numbers_with_an_exponent_and_no_point_are_numbers_with_either_parser() -> None:
    """YAML 1.1 read `2e1` as text (PyYAML), which failed as "not a number" in some fields and passed in
    others; they are the numbers YAML 1.2 reads, with libyaml and with the pure-Python parser alike."""
    from protocol_runner.protocol.yaml_doc import FAST_LOADER, SafeLoader, _compose_and_construct, parse_yaml

    text = "a: 2e1\nb: -1E-3\nc: 1_000e2\nd: '2e1'\ne: 2\nf: 2.5e1\ng: e1\nh: 1e\n"
    expected = {"a": 20.0, "b": -0.001, "c": 100000.0, "d": "2e1", "e": 2, "f": 25.0, "g": "e1", "h": "1e"}
    assert parse_yaml(text, "x.yaml")[0] == expected
    for loader in (SafeLoader, FAST_LOADER):
        if loader is not None:
            assert _compose_and_construct(text, loader)[1] == expected


def test_a_number_of_thousands_of_digits_is_refused_at_its_line_with_either_parser() -> None:
    from protocol_runner.errors import InvalidInput
    from protocol_runner.protocol.yaml_doc import SafeLoader, parse_yaml
    from protocol_runner.protocol.yaml_limits import MAX_NUMBER_CHARS, check_yaml_limits
    from protocol_runner.report.declared import protocol_document

    for digits in ("9" * 5000, "3." + "1" * 5000, "1" * (MAX_NUMBER_CHARS + 1)):
        text = f"name: x\nperiods: {digits}\n"
        with pytest.raises(
            InvalidInput, match=rf"^x\.yaml:2: a number written with {len(digits)} characters"
        ):
            parse_yaml(text, "x.yaml")
        with pytest.raises(InvalidInput, match=r"^x\.yaml:2: "):
            check_yaml_limits(text, "x.yaml", loader=SafeLoader)
        with pytest.raises(yaml.YAMLError):  # an archive's protocol text: the report says it cannot read it
            protocol_document(text)
    ok = f"name: x\nperiods: {'1' * MAX_NUMBER_CHARS}\nsetup: '{'9' * 5000}'\nnote: {'9' * 500} turns\n"
    assert parse_yaml(ok, "x.yaml")[0]["setup"] == "9" * 5000  # quoted text, and text that is not a number


@pytest.mark.parametrize(
    ("text", "where", "code"),
    [
        ('name: x\nlevel: "sl\\x1b[2Jow"\n', "p.yaml:2: level", 0x1B),
        ('name: x\nitems: [a, "b\\x07"]\n', "p.yaml:2: items[1]", 0x07),
        ('name: x\n"k\\x9b": 1\n', "p.yaml:2: k\\x9b", 0x9B),  # the message escapes it
    ],
    ids=["escape", "bell in a list", "C1 in a key"],
)
def test_control_characters_in_texts_are_refused_at_their_line(text: str, where: str, code: int) -> None:
    """A level label with terminal escapes passed --validate and --plan printed them raw."""
    assert message(text).startswith(f"{where}: control character U+{code:04X} in a text")


def test_tabs_and_newlines_in_texts_are_text() -> None:
    data, _ = yaml_doc.parse_yaml('a: "one\\ttwo"\nb: |\n  line 1\n  line 2\n', "p.yaml")
    assert data == {"a": "one\ttwo", "b": "line 1\nline 2\n"}
