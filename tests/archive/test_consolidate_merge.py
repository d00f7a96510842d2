"""`archive.consolidate.merge_units`: the archive holds what copying the units over one another in plan order
would give (a later unit's attribute or dataset wins, whether or not an earlier unit set the same value),
although they are added last to first without reading what a later unit already set."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from protocol_runner.archive.consolidate import merge_units

ROOT = {  # the root attributes of a test archive
    "protocol_name": "p",
    "protocol_sha256": "0" * 64,
    "mode": "dry-run",
    "seed": 0,
    "created_utc": "t0",
    "finished_utc": "t1",
    "status": "complete",
    "joint": "knee",
}


def _unit(path: Path, attrs: dict[str, object], trial: str) -> Path:
    with h5py.File(path, "w") as f:
        f.attrs["unit_step_id"] = f"trial:{trial}"  # a unit's own attribute, not the archive's
        f.create_dataset("configurations/config_01/energy_loss_j", data=[float(trial)])  # later replaces
        cfg = f.require_group("configurations/config_01")
        for key, value in attrs.items():
            cfg.attrs[key] = value
        cfg.create_group(f"trials/{trial}").attrs["status"] = "complete"
    return path


def test_later_units_attributes_win_and_repeats_are_kept(tmp_path: Path) -> None:
    units = [
        _unit(tmp_path / "a.h5", {"key": 1, "rom_deg": np.array([0.0, 90.0]), "status": "partial"}, "1"),
        _unit(tmp_path / "b.h5", {"key": 1, "rom_deg": np.array([0.0, 90.0]), "status": "partial"}, "2"),
        _unit(tmp_path / "c.h5", {"key": 1, "rom_deg": np.array([0.0, 95.0]), "status": "complete"}, "3"),
        _unit(tmp_path / "d.h5", {"key": 1, "rom_deg": np.array([0, 95]), "status": "complete"}, "4"),
    ]
    with h5py.File(tmp_path / "out.h5", "w") as out:
        merge_units(out, units)
        cfg = out["configurations/config_01"]
        assert cfg.attrs["key"] == 1 and cfg.attrs["status"] == "complete"
        # the last unit's value, with its own dtype (integers), not the equal-valued floats before it
        assert cfg.attrs["rom_deg"].dtype.kind == "i" and list(cfg.attrs["rom_deg"]) == [0, 95]
        assert sorted(cfg["trials"], key=int) == ["1", "2", "3", "4"]
        assert all(cfg[f"trials/{t}"].attrs["status"] == "complete" for t in "1234")
        assert cfg["energy_loss_j"][()].tolist() == [4.0]  # the last unit's dataset
        assert "unit_step_id" not in out.attrs


def test_the_archive_declares_checksums_only_when_every_unit_had_them(tmp_path: Path) -> None:
    """A session begun before checksums existed and resumed after: its old units have none, so the
    archive does not claim them (the report then reads it with the bounds checked only)."""
    from protocol_runner.archive.attrs import CHECKSUM_MARKER
    from protocol_runner.archive.checksums import mark
    from protocol_runner.archive.consolidate import ArchiveMeta, consolidate
    from protocol_runner.archive.h5util import put
    from protocol_runner.report.load import load_report_data

    def unit(name: str, *, summed: bool) -> Path:
        path = tmp_path / f"{name}.h5"
        with h5py.File(path, "w") as f:
            grp = f.require_group(f"configurations/config_01/trials/{name}/brace_on")
            if summed:
                put(grp, "angle_deg", np.linspace(0.0, 90.0, 500), "deg")
                mark(f)
            else:
                grp.create_dataset("angle_deg", data=np.linspace(0.0, 90.0, 500)).attrs["units"] = "deg"
        return path

    meta = ArchiveMeta(ROOT, "name: p\n", "p.yaml", '{"steps": []}', (), (), {"config_01": {"key": 1}})
    new = consolidate(tmp_path / "new.h5", [unit("1", summed=True), unit("2", summed=True)], meta)
    mixed = consolidate(tmp_path / "mixed.h5", [unit("3", summed=False), unit("4", summed=True)], meta)
    with h5py.File(new, "r") as f:
        assert f.attrs[CHECKSUM_MARKER] == "sha256"
    with h5py.File(mixed, "r") as f:
        assert CHECKSUM_MARKER not in f.attrs
    assert len(load_report_data(mixed).configurations[0].trials) == 2


def _attr_types(obj: h5py.HLObject) -> dict[str, tuple[bytes, object]]:
    """Each attribute's HDF5 type (its encoding: class, size, order, character set, padding) and value (a
    number's bytes: NaN compares)."""
    out: dict[str, tuple[bytes, object]] = {}
    for name in obj.attrs:
        value = obj.attrs[name]
        arr = np.asarray(value if not isinstance(value, h5py.Empty) else [])
        shown = arr.tobytes() if arr.dtype.kind in "biuf" else arr.tolist()
        out[name] = (
            h5py.h5a.open(obj.id, name.encode()).get_type().encode(),
            (shown, arr.dtype.str, arr.shape, type(value).__name__),
        )
    return out


def test_an_attribute_is_copied_with_the_type_and_values_h5py_would_write(tmp_path: Path) -> None:
    """Consolidation copies a unit's attributes through HDF5 directly: every kind a unit holds (text,
    numbers, booleans, arrays of them, empty ones) arrives as `archive.attrs[k] = unit.attrs[k]` writes it."""
    values: dict[str, object] = {
        "text": "brace on, Ø 12 mm",
        "texts": np.array(["a", "bé", ""], dtype=h5py.string_dtype()),
        "count": 3,
        "ratio": 0.1,
        "flag": True,
        "flags": np.array([True, False]),
        "codes": np.array([1, -2, 3], dtype=np.int64),
        "small": np.array([1, 2], dtype=np.int16),
        "floats": np.array([0.5, np.nan, -np.inf]),
        "single": np.float32(1.25),
        "none_yet": np.array([], dtype=np.float64),
        "empty": h5py.Empty("f8"),
    }
    unit = tmp_path / "unit.h5"
    with h5py.File(unit, "w") as f:
        f.require_group("configurations/config_01").attrs.update(values)
    with h5py.File(tmp_path / "by_h5py.h5", "w") as ref, h5py.File(unit, "r") as f:
        src = f["configurations/config_01"]
        dst = ref.require_group("configurations/config_01")
        for name in src.attrs:
            dst.attrs[name] = src.attrs[name]
        expected = _attr_types(dst)
    with h5py.File(tmp_path / "under.h5", "w") as out:
        merge_units(out, [unit])
        assert _attr_types(out["configurations/config_01"]) == expected
    assert len(expected) == len(values)


def test_a_later_units_dataset_replaces_an_earlier_units_group_whole(tmp_path: Path) -> None:
    """Copying the units over one another in plan order, a later unit's dataset takes the place of an
    earlier unit's group of the same name: none of the group's attributes or members remain."""
    earlier, later = tmp_path / "earlier.h5", tmp_path / "later.h5"
    with h5py.File(earlier, "w") as f:
        grp = f.require_group("configurations/config_01/summary")
        grp.attrs["note"] = "a group first"
        grp.create_dataset("n", data=[1])
        f["configurations/config_01"].attrs["kept"] = "only in the earlier unit"
    with h5py.File(later, "w") as f:
        f.create_dataset("configurations/config_01/summary", data=[2.0, 3.0]).attrs["units"] = "J"
    with h5py.File(tmp_path / "merged.h5", "w") as out:
        merge_units(out, [earlier, later])
        summary = out["configurations/config_01/summary"]
        assert isinstance(summary, h5py.Dataset) and summary[()].tolist() == [2.0, 3.0]
        assert dict(summary.attrs) == {"units": "J"}  # the group's "note" not carried over
        assert out["configurations/config_01"].attrs["kept"] == "only in the earlier unit"
