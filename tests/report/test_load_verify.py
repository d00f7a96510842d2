"""`load_report_data(verify=False)`: the session's own report skips re-reading the checksums of the archive
it has just consolidated from checked units (checksums and bounds); the data read are the same."""

from __future__ import annotations

import pickle
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.report.load import load_report_data


def _damaged(reference_archive: Path, tmp_path: Path) -> Path:
    """A copy of a dry run's archive (every dataset checksummed) whose first processed angle values were
    changed in place, the recorded sha256 kept."""
    archive = tmp_path / "archive.h5"
    shutil.copy(reference_archive, archive)
    with h5py.File(archive, "a") as h5:
        name = sorted(h5["configurations"])[0]
        trials = h5["configurations"][name]["joints/knee_flexion/trials"]
        ds = trials[sorted(trials)[0]]["processed"]["angle_deg"]
        values = ds[()]
        ds[:4] = values[:4] + np.float32(1.0)
    return archive


def test_without_verification_the_same_data_is_read(small_archive: Path) -> None:
    checked = load_report_data(small_archive, workers=1)
    unchecked = load_report_data(small_archive, workers=1, verify=False)
    assert [pickle.dumps(c) for c in unchecked.configurations] == [
        pickle.dumps(c) for c in checked.configurations
    ]  # every field, every array's values
    assert unchecked.session == checked.session
    assert unchecked.comparisons == checked.comparisons


def test_verification_is_what_names_a_damaged_dataset(reference_archive: Path, tmp_path: Path) -> None:
    archive = _damaged(reference_archive, tmp_path)
    with pytest.raises(InvalidInput, match="processed/angle_deg is damaged"):
        load_report_data(archive, workers=1)
    load_report_data(archive, workers=1, verify=False)  # the session's own report does not read them again


def test_without_verification_no_dataset_is_checked(
    small_archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from protocol_runner.archive import verify

    checked: list[str] = []
    real = verify.Checker.check
    monkeypatch.setattr(verify.Checker, "check", lambda self, ds: checked.append(ds.name) or real(self, ds))
    load_report_data(small_archive, workers=1, verify=False)
    assert checked == []
    load_report_data(small_archive, workers=1)
    assert any(name.endswith("/processed/angle_deg") for name in checked)  # every dataset, when verifying
