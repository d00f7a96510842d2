"""Every attribute that carries a result or an identity (fitted values, verdicts, statuses, counts, versions)
is checksummed like the datasets (archive/checksums.py, docs/archive.md "Checksums"): one flipped bit in a
stored Bouc-Wen parameter is named by `--verify` and refused by `--report` and `--export` (exit 2), while
archives written before attribute checksums still open, verify and report."""

from __future__ import annotations

import shutil
import struct
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.attrs import ATTRIBUTE_DIGESTS, ATTRIBUTE_MARKER
from protocol_runner.archive.checksums import (
    UNSUMMED_ATTRS,
    attribute_digest,
    recorded_attribute_digests,
    seal_attributes,
    stored_attribute_digests,
)
from protocol_runner.archive.h5util import put_attrs
from protocol_runner.archive.verify import Checker
from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput
from tests.archive.test_checksums import flip_bit
from tests.report.report_archive_builder import small_spec, write_archive


@pytest.fixture
def archive(tmp_path: Path, reference_archive: Path) -> Path:
    copy = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, copy)
    return copy


def _fit_with_a(path: Path) -> tuple[str, float]:
    with h5py.File(path, "r") as f:
        found: list[tuple[str, float]] = []
        f.visititems(
            lambda name, obj: (
                found.append((obj.name, float(obj.attrs["A"])))
                if isinstance(obj, h5py.Group) and name.endswith("fits/bouc_wen") and "A" in obj.attrs
                else None
            )
        )
    assert found, "the reference session fits Bouc-Wen"
    return found[0]


def _halve_in_file(path: Path, value: float) -> None:
    """Flip the lowest exponent bit of the stored float64 `value` (the attribute's bytes in its object
    header): the value read back is half or twice what was written."""
    data = path.read_bytes()
    packed = struct.pack("<d", value)
    assert data.count(packed) == 1
    flip_bit(path, data.index(packed) + 6, bit=4)


def test_every_attribute_of_a_session_archive_has_a_matching_checksum(reference_archive: Path) -> None:
    with h5py.File(reference_archive, "r") as f:
        assert f.attrs[ATTRIBUTE_MARKER] == "sha256"
        objects: list[h5py.HLObject] = [f]
        f.visititems(lambda _, obj: objects.append(obj))
        for obj in objects:
            covered = {name for name in obj.attrs if name not in UNSUMMED_ATTRS}
            assert (recorded_attribute_digests(obj) or {}) == stored_attribute_digests(obj), obj.name
            assert set(recorded_attribute_digests(obj) or {}) == covered, obj.name
        assert {"status", "schema_version", "protocol_sha256"} <= set(recorded_attribute_digests(f) or {})


def test_a_flipped_bit_in_a_fitted_parameter_is_named_by_verify_report_and_export(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fit, a = _fit_with_a(archive)
    _halve_in_file(archive, a)
    with h5py.File(archive, "r") as f:
        assert float(f[fit].attrs["A"]) in (a / 2, a * 2)  # what the report would show without the checksum
    named = f"{fit}@A is damaged"
    assert main(["--verify", str(archive)]) == 2
    err = capsys.readouterr().err
    assert named in err and "1 problem" in err
    for args in (
        ["--report", str(archive), "--output", str(archive.with_suffix(".html"))],
        ["--export", str(archive), "--output", str(archive.parent / "tables")],
        ["--report", str(archive), "--export-mat", str(archive.parent / "mat")],
        ["--report", str(archive), "--reprocess"],
    ):
        assert main(args) == 2, args
        assert named in capsys.readouterr().err, args
    assert not archive.with_suffix(".html").exists()
    assert not (archive.parent / "tables" / "configurations.csv").exists()


def test_a_changed_status_text_and_a_removed_verdict_are_named(archive: Path) -> None:
    """Changed as an editor would (h5py), not by a bit flip: the checksum still tells."""
    with h5py.File(archive, "r+") as f:
        f.attrs["status"] = "complete "
    with pytest.raises(InvalidInput, match="/@status is damaged"), h5py.File(archive, "r") as f:
        Checker.of(f, archive).check_tree(f, skip=("configurations",))
    with h5py.File(archive, "r+") as f:
        f.attrs["status"] = "complete"
        group = next(g for g in f["expectations"].values() if isinstance(g, h5py.Group))
        del group.attrs["verdict"]
        name = group.name
    with h5py.File(archive, "r") as f:
        assert any(f"{name}@verdict is missing" in p for p in Checker.of(f, archive).problems(f))


def test_an_attribute_without_checksum_in_a_file_that_declares_them_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as f:
        f.create_group("g").attrs["n_trials"] = 3
        seal_attributes(f)
    with h5py.File(path, "r+") as f:
        f["g"].attrs["rmse_nm"] = 0.5  # written around the archive's writers
    with h5py.File(path, "r") as f:
        assert Checker.of(f, path).problems(f) == [
            f"{path}: /g@rmse_nm has no checksum although the file declares one on every attribute"
        ]


def test_put_attrs_keeps_a_finished_file_checksummed(tmp_path: Path) -> None:
    """Writers of a finished archive (the verdicts) go through put_attrs and need nothing else."""
    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as f:
        f.create_group("expectations")
        seal_attributes(f)
    with h5py.File(path, "r+") as f:
        group = f["expectations"].create_group("e1")
        put_attrs(group, "expectation", {"verdict": "met", "dry_run": 1, "reason": None})
        put_attrs(group, "expectation", {"verdict": "not met"})
    with h5py.File(path, "r") as f:
        assert Checker.of(f, path).problems(f) == []
        assert set(recorded_attribute_digests(f["expectations/e1"]) or {}) == {"verdict", "dry_run"}


@pytest.mark.parametrize(
    "value",
    [
        np.float64(1.0712),
        np.int64(4),
        True,
        "met",
        b"met",
        np.array([1.5, 2.5]),
        np.array(["a", "b"], dtype="S"),
    ],
    ids=["float", "int", "bool", "str", "bytes", "floats", "strings"],
)
def test_each_kind_of_attribute_detects_a_changed_value(tmp_path: Path, value: object) -> None:
    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as f:
        f.attrs["x"] = value
        seal_attributes(f)
        recorded = (recorded_attribute_digests(f) or {})["x"]
        assert recorded == attribute_digest(f.attrs["x"])
        f.attrs["x"] = np.float64(0.5356) if not isinstance(value, str | bytes) else "not met"
        assert attribute_digest(f.attrs["x"]) != recorded


def test_an_archive_written_before_attribute_checksums_opens_verifies_and_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = write_archive(tmp_path / "archive.h5", small_spec())
    with h5py.File(old, "r") as f:
        assert ATTRIBUTE_MARKER not in f.attrs and ATTRIBUTE_DIGESTS not in f.attrs
    assert main(["--report", str(old), "--output", str(tmp_path / "report.html")]) == 0
    assert main(["--export", str(old), "--output", str(tmp_path / "tables")]) == 0
    main(["--verify", str(old)])  # no dataset checksums either: says it cannot be verified
    out = capsys.readouterr()
    assert (tmp_path / "report.html").is_file() and (tmp_path / "tables" / "configurations.csv").is_file()
    assert "cannot be verified" in out.err


def test_verify_says_when_the_attributes_carry_no_checksum(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A session archive as written before attribute checksums: its datasets verify, its attributes cannot."""
    with h5py.File(archive, "r+") as f:
        objects: list[h5py.HLObject] = [f]
        f.visititems(lambda _, obj: objects.append(obj))
        for obj in objects:
            if ATTRIBUTE_DIGESTS in obj.attrs:
                del obj.attrs[ATTRIBUTE_DIGESTS]
        del f.attrs[ATTRIBUTE_MARKER]
    assert main(["--verify", str(archive)]) == 0
    out = capsys.readouterr().out
    assert (
        "every checksum matches; its attributes carry no checksum (written before attribute checksums)" in out
    )
    assert main(["--report", str(archive), "--output", str(archive.with_suffix(".html"))]) == 0
