"""The rig file is part of what a session ran with: a lab's own rig file beside the protocol is copied into the
session (so the session resumes from its own copy), a changed rig is refused on resume unless --force, and
the archive carries the rig's text (`/rig`) and sha256 (root `rig_sha256`) so `--reprocess` needs nothing
beside the archive (docs/session.md, docs/archive.md)."""

from __future__ import annotations

import dataclasses
import hashlib
import shutil
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive.reprocess import reprocess_archive
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.resources import packaged_rigs_dir
from protocol_runner.session.setup import (
    create_session,
    load_session_protocol,
    read_session_info,
    write_session_info,
)

from .conftest import run_dry

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"


def lab_campaign(folder: Path) -> Path:
    """The shipped knee campaign, copied with its files, against a lab's own copy of the RSST rig file."""
    shutil.copytree(PROTOCOLS, folder)
    shutil.copyfile(packaged_rigs_dir() / "rsst.yaml", folder / "lab_rig.yaml")
    path = folder / "knee_phase1.yaml"
    text = path.read_text(encoding="utf-8")
    assert "\nrig: rsst" in text
    path.write_text(text.replace("\nrig: rsst", "\nrig: lab_rig.yaml", 1), encoding="utf-8")
    return path


def new_session(tmp_path: Path, protocol: Path) -> Path:
    session = tmp_path / "session"
    create_session(session, load_protocol(protocol), mode="dry-run", seed=1, only=(), realtime=False)
    return session


def test_a_lab_rig_file_is_kept_with_the_session_and_resumes_without_the_original(tmp_path: Path) -> None:
    protocol = lab_campaign(tmp_path / "campaign")
    session = new_session(tmp_path, protocol)
    kept = session / "protocol" / "lab_rig.yaml"
    assert kept.read_bytes() == (protocol.parent / "lab_rig.yaml").read_bytes()
    info = read_session_info(session)
    digest = hashlib.sha256(kept.read_bytes()).hexdigest()
    assert info.files_sha256["lab_rig.yaml"] == digest and info.rig_sha256 == digest

    shutil.rmtree(protocol.parent)  # the campaign folder moved away: the session has all it needs
    loaded, plan, changed = load_session_protocol(session, info, force=False)
    assert loaded.rig_source.sha256 == digest and not changed and len(plan.steps) > 0


def test_an_edited_copy_of_the_lab_rig_is_refused_by_name_unless_forced(tmp_path: Path) -> None:
    session = new_session(tmp_path, lab_campaign(tmp_path / "campaign"))
    kept = session / "protocol" / "lab_rig.yaml"
    kept.write_text(kept.read_text(encoding="utf-8") + "\n# retuned\n", encoding="utf-8")
    info = read_session_info(session)
    with pytest.raises(InvalidInput, match=r"lab_rig\.yaml \(changed\)"):
        load_session_protocol(session, info, force=False)
    _, _, changed = load_session_protocol(session, info, force=True)
    assert changed  # recorded as an override by the resume


def test_a_shipped_rig_that_changed_since_the_session_began_is_refused_unless_forced(tmp_path: Path) -> None:
    session = new_session(tmp_path, PROTOCOLS / "ankle_phase2.yaml")
    info = read_session_info(session)
    shipped = (packaged_rigs_dir() / "rsst.yaml").read_bytes()
    assert info.rig_sha256 == hashlib.sha256(shipped).hexdigest()
    assert load_session_protocol(session, info, force=False)[2] is False

    # the session began under another version of rsst.yaml (as after a software upgrade)
    older = dataclasses.replace(info, rig_sha256=hashlib.sha256(shipped + b"# v0\n").hexdigest())
    write_session_info(session, older)
    with pytest.raises(InvalidInput, match=r"rigs/rsst\.yaml: the rig file changed since the session began"):
        load_session_protocol(session, read_session_info(session), force=False)
    assert load_session_protocol(session, read_session_info(session), force=True)[2] is True


def test_a_damaged_rig_sha256_in_session_json_names_the_field(tmp_path: Path) -> None:
    session = new_session(tmp_path, PROTOCOLS / "ankle_phase2.yaml")
    path = session / "session.json"
    path.write_text(path.read_text().replace('"rig_sha256": "', '"rig_sha256": "zz', 1))
    with pytest.raises(InvalidInput, match="field 'rig_sha256'"):
        read_session_info(session)


def test_the_archive_holds_the_rig_as_run(reference_archive: Path) -> None:
    shipped = (packaged_rigs_dir() / "rsst.yaml").read_bytes()
    with h5py.File(reference_archive, "r") as f:
        assert f["rig"][()] == shipped
        assert f["rig"].attrs["filename"] == "rigs/rsst.yaml"
        assert f.attrs["rig_sha256"] == hashlib.sha256(shipped).hexdigest()


def test_an_archive_of_a_lab_rig_reprocesses_with_nothing_beside_it(tmp_path: Path) -> None:
    protocol = lab_campaign(tmp_path / "campaign")
    session = tmp_path / "lab"
    assert run_dry(session, protocol=str(protocol)) == 0
    alone = tmp_path / "elsewhere" / "archive.h5"
    alone.parent.mkdir()
    shutil.move(session / "archive.h5", alone)
    shutil.rmtree(protocol.parent)
    shutil.rmtree(session)
    out = reprocess_archive(alone)
    with h5py.File(alone, "r") as a, h5py.File(out, "r") as b:
        assert b["rig"][()] == a["rig"][()] and b.attrs["reprocessed_from"] == "archive.h5"
        assert sorted(b["configurations"]) == sorted(a["configurations"])


def test_the_matlab_export_carries_the_rig_as_run(tmp_path: Path, reference_archive: Path) -> None:
    from scipy.io import loadmat

    from protocol_runner.archive.export import export_mat

    export_mat(reference_archive, tmp_path / "mat")
    s = loadmat(tmp_path / "mat" / "session.mat", simplify_cells=True)
    assert s["rig"] == (packaged_rigs_dir() / "rsst.yaml").read_text(encoding="utf-8")
    assert s["rig_filename"] == "rigs/rsst.yaml"
