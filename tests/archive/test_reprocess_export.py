"""--reprocess redoes processing from the archive's raw data only; --export-mat writes MATLAB files."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.io import loadmat

from protocol_runner.archive.export import export_mat
from protocol_runner.archive.reprocess import reprocess_archive
from protocol_runner.errors import InvalidInput

from ..session.conftest import archive_contents

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def archive_alone(reference_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reference archive copied somewhere with no session directory and no protocol file."""
    target = tmp_path_factory.mktemp("alone") / "archive.h5"
    shutil.copyfile(reference_archive, target)
    return target


def test_reprocess_with_other_cutoff_changes_processed_data_and_nothing_else(
    archive_alone: Path, tmp_path: Path
) -> None:
    text = (REPO / "protocols" / "knee_phase1.yaml").read_text()
    other = text.replace(
        "filter: {kind: butterworth, order: 10, cutoff: 0.10}",
        "filter: {kind: butterworth, order: 10, cutoff: 0.02}",
    )
    assert other != text
    proto = tmp_path / "other_cutoff.yaml"
    proto.write_text(other)
    out = reprocess_archive(archive_alone, protocol_file=str(proto), output=tmp_path / "re.h5")
    before = archive_contents(archive_alone)
    after = archive_contents(out)
    changed = {k for k in before if k in after and before[k] != after[k]}
    derived = ("/processed", "energy_loss_j", "energy_cycle_trial", "/fits/", "comparisons/")
    assert any("/processed/brace_torque_nm" in k for k in changed)
    unexpected = sorted(k for k in changed if not any(d in k for d in derived))
    assert not unexpected, unexpected
    raw = [k for k in before if "/brace_on/" in k or "/brace_off/" in k or k.startswith("calibration/")]
    assert raw and all(before[k] == after[k] for k in raw)
    with h5py.File(out, "r") as f:
        assert f.attrs["reprocessed_from"] == "archive.h5"
        assert '"cutoff": 0.02' in f.attrs["reprocessing_settings"]


def test_reprocess_with_archived_settings_reproduces_the_session(archive_alone: Path, tmp_path: Path) -> None:
    out = reprocess_archive(archive_alone, output=tmp_path / "same.h5")
    before = archive_contents(archive_alone)
    after = archive_contents(out)
    derived = [
        k for k in before if any(d in k for d in ("/processed/", "energy_loss_j", "/fits/", "comparisons/"))
    ]
    assert any("/fits/bouc_wen" in k for k in derived)
    different = sorted(k for k in derived if before[k] != after.get(k))
    assert not different, different[:10]


def test_reprocess_refuses_a_foreign_file(tmp_path: Path) -> None:
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(InvalidInput):
        reprocess_archive(foreign)


def test_export_mat_writes_each_configuration(archive_alone: Path, tmp_path: Path) -> None:
    files = export_mat(archive_alone, tmp_path / "mat")
    assert [p.name for p in files] == ["config_12.mat", "session.mat"]
    m = loadmat(files[0], squeeze_me=True, struct_as_record=False)
    with h5py.File(archive_alone, "r") as f:
        cfg = f["configurations/config_12/joints/knee_flexion"]  # one joint's data: at the file's top
        assert int(m["configuration"].key) == 12
        np.testing.assert_allclose(m["energy_loss_j"], cfg["energy_loss_j"][:])
        np.testing.assert_allclose(
            m["trial_1"].brace_torque_nm, cfg["trials/1/processed/brace_torque_nm"][:], rtol=1e-6
        )
        assert float(m["bouc_wen"].A) == pytest.approx(float(cfg["fits/bouc_wen"].attrs["A"]))
