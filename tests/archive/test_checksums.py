"""Every dataset of a unit or an archive carries a sha256 checksum (archive/checksums.py): one flipped bit
anywhere in a dataset's stored bytes is named by `--verify`, refused by `--report` and `--reprocess`, and a
damaged unit is refused by consolidation."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.attrs import CHECKSUM_MARKER, DIGEST
from protocol_runner.archive.checksums import digest_of_stored
from protocol_runner.archive.h5util import put, put_text
from protocol_runner.archive.verify import Checker
from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput

RAW = "/configurations/config_12/trials/2/brace_on/joints/knee_flexion/torque_nm"  # a raw trial signal, gzip-compressed chunks
ENERGY = "/configurations/config_12/joints/knee_flexion/energy_loss_j"  # a few values, stored uncompressed


def flip_bit(path: Path, offset: int, bit: int = 4) -> None:
    with path.open("r+b") as fh:
        fh.seek(offset)
        byte = fh.read(1)[0]
        fh.seek(offset)
        fh.write(bytes([byte ^ (1 << bit)]))


def stored_offset(path: Path, name: str) -> int:
    """A byte inside the stored data of dataset `name` (the middle of its first chunk, or of its block)."""
    with h5py.File(path, "r") as f:
        ds = f[name]
        if ds.chunks is None:
            return int(ds.id.get_offset()) + ds.id.get_storage_size() // 2
        info = ds.id.get_chunk_info(0)
        return int(info.byte_offset) + int(info.size) // 2


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = main(list(args))
    return code, capsys.readouterr().err


@pytest.fixture
def archive(tmp_path: Path, reference_archive: Path) -> Path:
    copy = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, copy)
    return copy


def test_every_dataset_of_a_session_archive_has_a_matching_checksum(
    reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with h5py.File(reference_archive, "r") as f:
        assert f.attrs[CHECKSUM_MARKER] == "sha256"
        datasets: list[h5py.Dataset] = []
        f.visititems(lambda _, obj: datasets.append(obj) if isinstance(obj, h5py.Dataset) else None)
        kinds = {("text" if h5py.check_string_dtype(ds.dtype) else ds.dtype.kind) for ds in datasets}
        assert {"text", "f", "i", "u"} <= kinds  # strings, floats, ADC and DAC codes
        for ds in datasets:
            assert ds.attrs[DIGEST] == digest_of_stored(ds), ds.name
    assert main(["--verify", str(reference_archive)]) == 0
    out = capsys.readouterr().out
    assert f"{len(datasets)} datasets and " in out and "attributes, every checksum matches" in out


def test_a_flipped_bit_in_a_raw_trial_is_named_by_verify_report_and_reprocess(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    flip_bit(archive, stored_offset(archive, RAW))
    for args in (
        ("--verify", str(archive)),
        ("--report", str(archive), "--output", str(archive.with_suffix(".html"))),
        ("--report", str(archive), "--reprocess"),
    ):
        code, err = run(capsys, *args)
        assert code == 2, args
        assert f"dataset {RAW} is damaged" in err and "Traceback" not in err, err
    assert not archive.with_suffix(".html").exists()
    assert not list(archive.parent.glob("*.reprocessed*"))  # nothing made from damaged data


def test_a_flipped_bit_in_an_energy_value_no_longer_passes_silently(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Uncompressed data have no other protection: the flip changes the value HDF5 returns."""
    with h5py.File(archive, "r") as f:
        before = f[ENERGY][()]
    flip_bit(archive, stored_offset(archive, ENERGY), bit=6)
    with h5py.File(archive, "r") as f:
        after = f[ENERGY][()]
    assert not np.array_equal(before, after)  # what the report would have shown without the checksum
    code, err = run(capsys, "--report", str(archive), "--output", str(archive.with_suffix(".html")))
    assert code == 2 and f"dataset {ENERGY} is damaged" in err
    code, err = run(capsys, "--verify", str(archive))
    assert code == 2 and ENERGY in err and "1 problem" in err


def test_a_flipped_bit_in_the_protocol_text_is_named(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Strings are stored outside the dataset (HDF5's global heap): their checksum covers them too."""
    with h5py.File(archive, "r") as f:
        text = f["protocol"][()]
    data = archive.read_bytes()
    offset = data.index(text[200:260])  # a stretch of the protocol's YAML inside the file
    assert data.count(text[200:260]) == 1
    flip_bit(archive, offset + 10, bit=0)
    code, err = run(capsys, "--verify", str(archive))
    assert code == 2 and "dataset /protocol is damaged" in err


@pytest.mark.parametrize(
    "write",
    [
        lambda g: put(g, "x", np.float64(2.5), "s"),  # scalar
        lambda g: put(g, "x", np.array([1, 2, 3], dtype=np.int32), "counts"),  # tiny, contiguous
        lambda g: put(g, "x", np.linspace(0.0, 1.0, 5000), "s"),  # chunked, gzip
        lambda g: put_text(g, "x", "some text: é"),
        lambda g: put_text(g, "x", ["a", "bb", ""]),
    ],
    ids=["scalar", "tiny", "compressed", "text", "lines"],
)
def test_each_kind_of_dataset_detects_any_changed_value(tmp_path: Path, write) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        ds = write(f)
        checker = Checker("u.h5", cap=10**6, strict=True)
        checker.check(ds)  # intact
        if h5py.check_string_dtype(ds.dtype):
            recorded = ds.attrs[DIGEST]
            del f["x"]
            ds = f.create_dataset("x", data="some text: e", dtype=h5py.string_dtype())
            ds.attrs[DIGEST] = recorded
        else:
            value = ds[()]
            changed = np.array(value, copy=True)
            changed.reshape(-1)[0] += 1
            ds[()] = changed
        with pytest.raises(InvalidInput, match="dataset /x is damaged"):
            checker.check(ds)


def test_the_checksum_is_of_the_values_not_of_how_they_are_stored(tmp_path: Path) -> None:
    """The same values stored with other filters and chunks (an archive written by an earlier version keeps
    some float32 signals unshuffled, in chunks deflated by another zlib encoder) carry the same digest: such
    an archive still passes --verify."""
    values = np.round(np.sin(np.arange(20_000) / 300.0) * 4096) / 4096  # a quantised signal
    with h5py.File(tmp_path / "u.h5", "w") as f:
        recorded = put(f, "x", values, "deg", dtype=np.float32).attrs[DIGEST]
        checker = Checker("u.h5", cap=10**6, strict=True)
        for name, layout in {
            "unshuffled": {"chunks": (8192,), "compression": "gzip", "compression_opts": 6},
            "contiguous": {},
        }.items():
            ds = f.create_dataset(name, data=values.astype(np.float32), **layout)
            ds.attrs[DIGEST] = recorded
            checker.check(ds)


def test_a_dataset_without_checksum_in_a_checksummed_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        ds = f.create_dataset("x", data=np.arange(3))
        with pytest.raises(InvalidInput, match="has no checksum"):
            Checker("u.h5", cap=10**6, strict=True).check(ds)
        Checker("u.h5", cap=10**6, strict=False).check(ds)  # an archive written before checksums


def test_consolidation_refuses_a_damaged_unit_and_resume_redoes_it(
    tmp_path: Path, reference_archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.session.conftest import assert_same_data

    session = tmp_path / "session"
    shutil.copytree(reference_archive.parent, session)
    (session / "archive.h5").unlink()
    unit = session / "units" / "trial__k12__on__2.h5"
    flip_bit(unit, stored_offset(unit, RAW))
    code, err = run(capsys, "--verify", str(session))
    assert code == 2 and f"{unit}: dataset {RAW} is damaged" in err
    code, err = run(capsys, "--report", str(session))  # assembles the archive from the units first
    assert code == 2 and f"{unit} is damaged" in err and "--resume" in err
    assert not (session / "archive.h5").exists() and not (session / "archive.h5.partial").exists()
    assert main(["--resume", str(session), "--yes"]) == 0
    assert_same_data(reference_archive, session / "archive.h5")
    assert main(["--verify", str(session)]) == 0


def test_a_unit_seals_datasets_written_without_the_archive_helpers(tmp_path: Path) -> None:
    from protocol_runner.archive.units import write_unit

    def fill(f: h5py.File) -> None:
        f.create_dataset("configurations/config_01/extra", data=np.arange(10.0))  # plain h5py

    record = write_unit(tmp_path, "trial:k01:on:1", fill)
    with h5py.File(tmp_path / record.file, "r") as f:
        ds = f["configurations/config_01/extra"]
        assert ds.attrs[DIGEST] == digest_of_stored(ds)
        assert f.attrs[CHECKSUM_MARKER] == "sha256"


def test_reprocessing_keeps_every_dataset_checksummed(
    archive: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from protocol_runner.archive.reprocess import reprocess_archive

    out = reprocess_archive(archive)
    assert main(["--verify", str(out)]) == 0
    assert "every checksum matches" in capsys.readouterr().out
