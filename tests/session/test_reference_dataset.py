"""A protocol that names an EMU reference dataset (§5.6) gets it copied into the archive and compared."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np

from .conftest import run_dry

REPO = Path(__file__).resolve().parents[2]


def test_reference_dataset_is_archived_and_reported(tmp_path: Path) -> None:
    work = tmp_path / "protocols"
    shutil.copytree(REPO / "protocols", work)
    angle = np.linspace(5.0, 100.0, 50)
    torque = 0.3 * (angle - 20.0)
    rows = "\n".join(f"{a:.3f},{t:.3f}" for a, t in zip(angle, torque, strict=True))
    (work / "emu_reference.csv").write_text(
        "# test reference (not EMU data)\nangle_deg,torque_nm\n" + rows + "\n"
    )
    text = (work / "knee_phase1.yaml").read_text()
    edited = text.replace("reference_dataset: null", "reference_dataset: emu_reference.csv")
    assert edited != text
    (work / "emu.yaml").write_text(edited)
    session = tmp_path / "s"
    assert run_dry(session, only=[27], protocol=str(work / "emu.yaml")) == 0
    with h5py.File(session / "archive.h5", "r") as f:
        ref = f["reference/emu_reference"]
        np.testing.assert_allclose(ref["angle_deg"][:], angle, atol=1e-3)
        assert ref["torque_nm"].attrs["units"] == "N*m" and ref.attrs["source"] == "emu_reference.csv"
    assert (session / "protocol" / "emu_reference.csv").is_file()  # the session is self-contained
    html = (session / "report.html").read_text()
    assert "emu_reference" in html
