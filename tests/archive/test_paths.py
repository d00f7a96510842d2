"""docs/archive.md states the layout that archive/paths.py and archive/attrs.py own: every group, every
dataset with its unit, and every attribute of each kind of object."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive import attrs, paths
from protocol_runner.archive.h5util import put_attrs

DOC = (Path(__file__).resolve().parents[2] / "docs" / "archive.md").read_text(encoding="utf-8")


def _between(start: str, end: str) -> str:
    i = DOC.index(start)
    return DOC[i : DOC.index(end, i + len(start))]


def _line_with(text: str) -> str:
    return next(line for line in DOC.splitlines() if text in line)


SECTIONS = {
    "recording": _between("### `trials/<n>/brace_on`", "### `trials/<n>/processed`"),
    "processed": _between("### `trials/<n>/processed`", "### Results"),
    "configuration": _line_with("| `energy_loss_j` (J)"),
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
        f"{paths.TRIALS}/<n>/{paths.PROCESSED}",
        f"{paths.FITS}/bouc_wen",
        f"{paths.FITS}/spring",
        f"{paths.FITS}/elements",
    ]
    roots = [
        "/" + paths.calibration_path("<set>", "<when>"),
        "/" + paths.comparison_path("<name>"),
        f"/{paths.REFERENCE}/<name>",
        f"/{paths.CHECKLISTS}/<step>",
        f"/{paths.CONFIGURATIONS}/<name>",
    ]
    assert [p for p in suffixes + roots if f"`{p}`" not in DOC] == []


ATTRIBUTE_SECTIONS = {
    "root": _between("## Root", "| dataset | meaning |"),
    "dataset": _between("# The archive", "## Root") + _between("## Checksums", "## Bounds"),
    "any": _between("## Checksums", "## Bounds"),
    "protocol": _line_with("| `/protocol`"),
    "rig": _line_with("| `/rig`"),
    "unit": _between("The session directory's unit files", "## `/calibration"),
    "checklist": _line_with("| `/session/checklists/<step>`"),
    "calibration": _between("## `/calibration/<set>/<when>`", "One group `joints/<joint>` per joint"),
    "calibration_joint": _between("One group `joints/<joint>` per joint", "## `/configurations"),
    "configuration": _between("## `/configurations/<name>`", "### `trials"),
    "recording": _between("Attributes of the trial group", "Attributes of `joints/<joint>`"),
    "recording_joint": _between("Attributes of `joints/<joint>`", "In a `brace_off` trial"),
    "scaling": _between("In a `brace_off` trial", "Every `joints/<joint>` of a trial"),
    "stream": _between("Every `joints/<joint>` of a trial", "### `trials/<n>/processed`"),
    "processed": SECTIONS["processed"],
    "energy_loss": SECTIONS["configuration"],
    "bouc_wen": SECTIONS["bouc_wen"],
    "elements": SECTIONS["elements"],
    "element_model": _line_with("| `fits/element_model`"),
    "models": _line_with("| `fits/models`"),
    "prediction": _line_with("| `/predictions`"),
    "spring": SECTIONS["spring"],
    "reference": SECTIONS["reference"],
    "comparison": _between("## `/comparisons/<name>`", "## `/expectations"),
    "expectations": _between("## `/expectations/<id>`", "## Checksums"),
    "expectation": _between("## `/expectations/<id>`", "## Checksums"),
}


def test_every_kind_of_object_has_a_documented_section() -> None:
    assert sorted(attrs.ATTRIBUTES) == sorted(ATTRIBUTE_SECTIONS)


@pytest.mark.parametrize("kind", sorted(attrs.ATTRIBUTES))
def test_every_attribute_is_documented(kind: str) -> None:
    """A name added to archive/attrs.py and not to docs/archive.md fails here."""
    text = ATTRIBUTE_SECTIONS[kind]
    assert [name for name in attrs.ATTRIBUTES[kind] if f"`{name}`" not in text] == []


@pytest.mark.parametrize("kind", sorted(attrs.DYNAMIC))
def test_per_campaign_attribute_names_are_documented(kind: str) -> None:
    text = ATTRIBUTE_SECTIONS[kind]
    assert [p for p in attrs.DYNAMIC[kind].split(", ") if p not in text] == []


def test_a_writer_cannot_write_an_attribute_the_layout_does_not_name(tmp_path: Path) -> None:
    with h5py.File(tmp_path / "a.h5", "w") as f:
        g = f.create_group("x")
        with pytest.raises(ValueError, match="a processed has no attribute filter_cutof"):
            put_attrs(g, "processed", {"filter_cutof": 1.0})
        with pytest.raises(ValueError, match="per campaign"):
            put_attrs(g, "processed", {}, dynamic={"brace.anything": 1.0})
        assert list(g.attrs) == []  # refused before anything is written
        put_attrs(g, "elements", {"rmse_nm": 0.5}, dynamic={"springs.max_preload_mm": 3.0})
        assert dict(g.attrs) == {"rmse_nm": 0.5, "springs.max_preload_mm": 3.0}


def test_joint_groups_read_both_layouts(tmp_path) -> None:
    """A group keyed by joint gives its joints in the order its `joints` attribute lists them; a group of an
    archive written before groups were keyed by joint is its one joint's part, named by the root attribute."""
    import h5py
    import numpy as np

    from protocol_runner.archive.paths import joint_groups

    with h5py.File(tmp_path / "a.h5", "w") as f:
        old = f.create_group("old")
        old.create_dataset("energy_loss_j", data=[1.0])
        new = f.create_group("new")
        new.attrs["joints"] = np.array(["hip", "knee"], dtype=h5py.string_dtype())
        new.create_group("joints/knee")
        new.create_group("joints/hip")
        assert [(n, g.name) for n, g in joint_groups(old, "knee_flexion")] == [("knee_flexion", "/old")]
        assert [(n, g.name) for n, g in joint_groups(new, "hip, knee")] == [
            ("hip", "/new/joints/hip"),
            ("knee", "/new/joints/knee"),
        ]
