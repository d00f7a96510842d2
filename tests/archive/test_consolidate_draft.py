"""`archive.consolidate.draft`: units merged into `archive.h5.partial` ahead of the session's end, the later
ones added by `consolidate`, give exactly the archive a consolidation from scratch gives (a later unit's
attribute or dataset still wins), and the partial file is never taken for an archive."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.consolidate import ArchiveMeta, consolidate, draft

from .test_consolidate_merge import ROOT

META = ArchiveMeta(ROOT, "name: p\n", "p.yaml", '{"steps": []}', (), ("e",), {"config_01": {"key": 1}})


def _unit(path: Path, n: int) -> Path:
    """Unit `n`: repeats and changes its configuration's attributes, replaces a dataset, adds a trial, and
    (unit 3) puts a group where unit 2 put a dataset."""
    with h5py.File(path, "w") as f:
        f.attrs["unit_step_id"] = f"trial:{n}"
        cfg = f.require_group("configurations/config_01")
        cfg.attrs["status"] = "complete" if n >= 3 else "partial"
        cfg.attrs["rom_deg"] = np.array([0, 90 + n]) if n % 2 else np.array([0.0, 90.0])
        cfg.create_dataset("energy_loss_j", data=[float(n)] * n)
        cfg.create_group(f"trials/{n}").attrs["status"] = "complete"
        if n == 2:
            cfg.create_dataset("extra", data=[1, 2])
        if n == 3:
            cfg.create_group("extra").attrs["note"] = "a group now"
    return path


def _contents(path: Path) -> dict[str, object]:
    out: dict[str, object] = {}
    with h5py.File(path, "r") as f:
        f.visititems(
            lambda name, obj: out.update({name: obj[()].tobytes()} if isinstance(obj, h5py.Dataset) else {})
        )
        f.visititems(
            lambda name, obj: out.update(
                {f"{name}@{k}": (repr(v), np.asarray(v).dtype.str) for k, v in obj.attrs.items()}
            )
        )
        out.update({f"/@{k}": (repr(v), np.asarray(v).dtype.str) for k, v in f.attrs.items()})
    return out


@pytest.mark.parametrize("ahead", [0, 1, 2, 3, 4])
def test_a_draft_then_the_rest_is_the_archive_from_scratch(tmp_path: Path, ahead: int) -> None:
    units = [_unit(tmp_path / f"{n}.h5", n) for n in (1, 2, 3, 4)]
    (tmp_path / "scratch").mkdir()
    scratch = consolidate(tmp_path / "scratch" / "archive.h5", units, META)
    archive = tmp_path / "archive.h5"
    first = draft(archive, units[: ahead // 2])  # drafted twice: some units, then some more
    second = draft(archive, units[:ahead], first)
    assert second.files == tuple(units[:ahead]) and not archive.exists()
    with h5py.File(second.path, "r") as partial:
        assert "status" not in partial.attrs  # a partial file never claims a status
    consolidate(archive, units, META, second)
    assert _contents(archive) == _contents(scratch)
    assert not second.path.exists()
    with h5py.File(archive, "r") as f:
        assert list(f["configurations/config_01/energy_loss_j"][()]) == [4.0] * 4  # the last unit's
        assert isinstance(
            f["configurations/config_01/extra"], h5py.Group
        )  # unit 3's group over unit 2's data


def test_a_draft_that_does_not_lead_the_units_is_left_aside(tmp_path: Path) -> None:
    """A unit redone since the draft (another file first): consolidation starts afresh, same content."""
    units = [_unit(tmp_path / f"{n}.h5", n) for n in (1, 2, 3)]
    archive = tmp_path / "archive.h5"
    stale = draft(archive, [units[1]])  # drafted from unit 2 alone
    assert not stale.leads(units)
    consolidate(archive, units, META, stale)
    (tmp_path / "ref").mkdir()
    assert _contents(archive) == _contents(consolidate(tmp_path / "ref" / "archive.h5", units, META))


def test_a_failed_draft_leaves_no_partial_file(tmp_path: Path) -> None:
    units = [_unit(tmp_path / "1.h5", 1), tmp_path / "missing.h5"]
    archive = tmp_path / "archive.h5"
    first = draft(archive, units[:1])
    with pytest.raises(OSError):
        draft(archive, units, first)
    assert not first.path.exists() and not first.leads(units[:1]) and not archive.exists()
