"""The README's command table, `run-protocol --help` and the flag checks agree: every mode and flag the
README names exists, every one the parser has is in the README, and each row's flags apply to its mode."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from protocol_runner.cli import FLAG_MODES, MODES, RUN, build_parser, main

REPO = Path(__file__).resolve().parents[1]
FLAG = re.compile(r"--[a-z][a-z-]*")


def _readme_rows() -> list[str]:
    """The first cell (the command) of each row of the README's "Commands" table."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    assert len(rows) >= len(MODES)
    return [row.split("`")[1] for row in rows]


def _parser_flags() -> set[str]:
    """Every option of the usage line `--help` starts with, but --help and --version."""
    return set(FLAG.findall(build_parser().format_usage())) - {"--help", "--version"}


def test_every_flag_of_the_readme_is_in_help_and_every_option_in_the_readme() -> None:
    readme = {flag for row in _readme_rows() for flag in FLAG.findall(row)}
    help_text = build_parser().format_help()
    assert sorted(f for f in readme if f not in help_text) == []
    assert sorted(_parser_flags() - readme) == []
    assert set(MODES) <= readme


def test_every_mode_is_described_in_help() -> None:
    modes_section = build_parser().format_help().split("modes:", 1)[1].split("\n\n", 1)[0]
    described = set(FLAG.findall(modes_section))
    assert sorted(set(MODES) - described) == []


def test_each_readme_row_names_only_flags_that_apply_to_its_mode() -> None:
    for row in _readme_rows():
        flags = FLAG.findall(row)
        mode = next((f for f in flags if f in MODES), RUN)
        for flag in flags:
            if flag not in MODES:
                assert mode in FLAG_MODES[flag], f"README row `{row}`: {flag} does not apply to {mode}"


def test_with_no_arguments_the_hint_lists_every_mode(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    hint = capsys.readouterr().err.strip().splitlines()[-1]
    assert sorted(m for m in MODES if m not in hint) == []


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["knee_phase1.yaml", "--dry-run", "--yes"], ("--yes", "dry run")),
        (["--report", "x.h5", "--json"], ("--json", "--report")),
        (["--plan", "knee_phase1.yaml", "--output", "out.html"], ("--output", "--plan")),
        (["--verify", "x.h5", "--only", "3"], ("--only", "--verify")),
        (["--compare", "a.h5", "b.h5", "--seed", "3"], ("--seed", "--compare")),
        (["--export", "x.h5", "--session", "s"], ("--session", "--export")),
        (["--schema", "--dry-run"], ("--dry-run", "--schema")),
        (["knee_phase1.yaml", "--force"], ("--force", "a run")),
        (["--report", "x.h5", "--protocol-file", "p.yaml"], ("--protocol-file", "--reprocess")),
        (["--verify", "x.h5", "knee_phase1.yaml"], ("PROTOCOL knee_phase1.yaml", "--verify")),
    ],
)
def test_a_flag_that_does_not_apply_is_refused_naming_flag_and_command(
    argv: list[str],
    named: tuple[str, str],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)  # where a run would create sessions/
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert all(word in err for word in named), err
    assert "Traceback" not in err and not any(tmp_path.iterdir())


def test_schema_prints_the_shipped_schema(capsys: pytest.CaptureFixture[str]) -> None:
    from protocol_runner.protocol.schema import SCHEMA_FILE

    assert main(["--schema"]) == 0
    assert capsys.readouterr().out == SCHEMA_FILE.read_text(encoding="utf-8")
