"""docs/archive.md states the layout that archive/paths.py owns: every group and every dataset with its unit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from protocol_runner.archive import paths

DOC = (Path(__file__).resolve().parents[2] / "docs" / "archive.md").read_text(encoding="utf-8")


def _between(start: str, end: str) -> str:
    i = DOC.index(start)
    return DOC[i : DOC.index(end, i + len(start))]


def _line_with(text: str) -> str:
    return next(line for line in DOC.splitlines() if text in line)


SECTIONS = {
    "recording": _between("### `trials/<n>/brace_on`", "### `trials/<n>/processed`"),
    "processed": _between("### `trials/<n>/processed`", "### Results"),
    "configuration": _line_with("`energy_loss_j`"),
    "bouc_wen": _line_with("| `fits/bouc_wen`"),
    "spring": _line_with("| `fits/spring`"),
    "elements": _line_with("| `fits/elements`"),
    "reference": _between("## `/reference/<name>`", "## `/comparisons"),
}


@pytest.mark.parametrize("kind", sorted(paths.DATASETS))
def test_every_dataset_is_documented_with_its_unit(kind: str) -> None:
    text = SECTIONS[kind]
    missing = [
        f"{name} ({unit})"
        for name, unit in paths.DATASETS[kind].items()
        if not re.search(rf"`{name}`(?:, `\w+`)* (?:\({re.escape(unit)}\)|\| {re.escape(unit)} \|)", text)
    ]
    assert missing == []


def test_every_group_path_is_documented() -> None:
    base = paths.configuration_path(1)
    assert base == "configurations/config_01"  # `config_NN`, NN the key on two digits
    suffixes = [
        paths.recording_path(1, "<n>", "on")[len(base) + 1 :],
        paths.recording_path(1, "<n>", "off")[len(base) + 1 :],
        paths.processed_path(1, "<n>")[len(base) + 1 :],
        paths.fits_path(1)[len(base) + 1 :] + "/bouc_wen",
        paths.fits_path(1)[len(base) + 1 :] + "/spring",
        paths.fits_path(1)[len(base) + 1 :] + "/elements",
    ]
    roots = [
        "/" + paths.calibration_path("<set>", "<when>"),
        "/" + paths.comparison_path("<name>"),
        f"/{paths.REFERENCE}/<name>",
        f"/{paths.CHECKLISTS}/<step>",
        f"/{paths.CONFIGURATIONS}/<name>",
    ]
    assert [p for p in suffixes + roots if f"`{p}`" not in DOC] == []
