"""`--reprocess` with `fits.bouc_wen.backbone: elements` on the knee dry run: every
Bouc-Wen fit records which backbone it used, and where the device has elastic elements that is the
element fit's springs (the shipped protocol keeps the polynomial default)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive.reprocess import reprocess_archive
from protocol_runner.protocol.loader import load_protocol

REPO = Path(__file__).resolve().parents[2]


def test_reprocess_with_the_elements_backbone_records_it_per_fit(
    reference_archive: Path, tmp_path: Path
) -> None:
    text = (REPO / "protocols" / "knee_phase1.yaml").read_text()
    old = "bouc_wen: {enabled: true, starts: 8, cross_validate: true}"
    assert old in text
    proto = tmp_path / "elements.yaml"
    proto.write_text(
        text.replace(old, "bouc_wen: {enabled: true, starts: 2, cross_validate: true, backbone: elements}")
    )
    archive = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    out = reprocess_archive(archive, protocol_file=str(proto), output=tmp_path / "re.h5")
    seen = []
    with h5py.File(out, "r") as f:
        for name, cfg in f["configurations"].items():
            if "joints/knee_flexion/fits/bouc_wen" not in cfg:
                continue
            a = cfg["joints/knee_flexion/fits/bouc_wen"].attrs
            kind = str(a["backbone"])
            note = str(a["backbone_note"])
            seen.append(kind)
            assert math.isfinite(float(a["rmse_nm"])), name
            if kind == "elements":
                assert note.startswith("device elements, least squares"), (name, note)
                assert len(a["backbone_grid_angle_deg"]) == len(a["backbone_grid_torque_nm"]) > 2
            else:
                assert kind == "none" and note.startswith("not applicable"), (name, kind, note)
    assert "elements" in seen, seen


@pytest.mark.parametrize("name", ["knee_phase1.yaml", "ankle_phase2.yaml"])
def test_the_shipped_campaigns_keep_the_polynomial_backbone(name: str) -> None:
    loaded = load_protocol(REPO / "protocols" / name)
    assert loaded.protocol.fits.bouc_wen.backbone == "polynomial"
