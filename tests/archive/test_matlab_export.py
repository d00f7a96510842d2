"""--export-mat: every dataset and attribute of a dry-run archive is in the .mat files, with its value, its
unit, a valid MATLAB name, MATLAB's index base, double type and column orientation (docs/matlab.md)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from scipy.io import loadmat

from protocol_runner.archive.attrs import ATTRIBUTE_DIGESTS, ATTRIBUTE_MARKER
from protocol_runner.archive.checksums import seal_attributes, seal_attributes_of
from protocol_runner.archive.export import export_mat
from protocol_runner.archive.h5util import put_attrs
from protocol_runner.archive.matlab import matlab_name, put_field
from protocol_runner.archive.results import comparison_values
from protocol_runner.cli import main

from .former_layout import to_former_layout

MATLAB_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")


@pytest.fixture(scope="module")
def exported(reference_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(archive, export directory): the reference dry run (configuration 12) exported alone."""
    folder = tmp_path_factory.mktemp("export")
    archive = folder / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    export_mat(archive, folder / "mat")
    return archive, folder / "mat"


def _load(path: Path, squeeze: bool = True) -> dict[str, Any]:
    return loadmat(path, squeeze_me=squeeze, struct_as_record=False, chars_as_strings=True)


def _get(m: dict[str, Any], fields: list[str]) -> Any:
    value: Any = m[fields[0]]
    for name in fields[1:]:
        assert name in value._fieldnames, f"{'.'.join(fields)}: no field {name}"
        value = getattr(value, name)
    return value


#: For one joint the configuration's total over the joints is that joint's energy per cycle (docs/archive.md),
#: exported once.
ONE_JOINT_TOTALS = {"total_energy_loss_j": "energy_loss_j", "total_energy_cycle_trial": "energy_cycle_trial"}


def _where(path: str) -> tuple[str, list[str]]:
    """Where docs/matlab.md says the archive object at `path` of an archive of one joint is exported:
    (file, struct fields). The joint's part of a group keyed by joint (`<group>/joints/<joint>/...`) is in
    the group's struct itself, as in an archive written before groups were keyed by joint."""
    parts = re.sub(r"/joints(/[^/]+)?(?=/|$)", "", "/" + path.strip("/")).strip("/").split("/")
    if parts[0] != "configurations":
        return "session.mat", [matlab_name(p) for p in parts]
    cfg, rest = parts[1], [ONE_JOINT_TOTALS.get(p, p) for p in parts[2:]]
    if rest[:1] == ["trials"]:
        trial = f"trial_{rest[1]}"
        return f"{cfg}.mat", [trial, *(rest[3:] if rest[2:3] == ["processed"] else rest[2:])]
    if rest[:1] == ["fits"]:
        return f"{cfg}.mat", rest[1:]
    return f"{cfg}.mat", rest or ["configuration"]


def _assert_same(got: Any, stored: Any, what: str) -> None:
    arr = np.asarray(stored)
    if isinstance(stored, (bytes, str)) or arr.dtype.kind in "SO":
        texts = [v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(arr).tolist()]
        if isinstance(got, np.ndarray) and got.dtype.kind == "U" and got.size == 0:
            got = ""  # loadmat reads an empty char as an empty array
        assert [str(v) for v in np.atleast_1d(got).tolist()] == texts, what
    else:
        np.testing.assert_array_equal(
            np.asarray(got, dtype=float).reshape(-1), arr.astype(float).reshape(-1), err_msg=what
        )


def _datasets(group: h5py.Group) -> list[tuple[str, h5py.Dataset]]:
    found: list[tuple[str, h5py.Dataset]] = []
    group.visititems(lambda n, o: found.append((n, o)) if isinstance(o, h5py.Dataset) else None)
    return found


def test_every_dataset_is_exported_with_its_value_and_unit(exported: tuple[Path, Path]) -> None:
    archive, out = exported
    files = {p.name: _load(p) for p in sorted(out.glob("*.mat"))}
    assert sorted(files) == ["config_12.mat", "session.mat"]
    checked = 0
    with h5py.File(archive, "r") as f:

        def visit(name: str, obj: h5py.HLObject) -> None:
            nonlocal checked
            if not isinstance(obj, h5py.Dataset):
                return
            file, fields = _where(name)
            _assert_same(_get(files[file], fields), obj[()], f"{file}: {'.'.join(fields)} vs {name}")
            if "units" in obj.attrs:
                assert getattr(files[file]["units"], fields[-1]) == obj.attrs["units"], name
            checked += 1

        f.visititems(visit)
        # the configuration file also holds its set's calibration records
        cfg = files["config_12.mat"]
        cal = f[f"calibration/{f['configurations/config_12'].attrs['set']}"]
        for when, group in cal.items():
            datasets = _datasets(group)
            assert datasets
            for name, ds in datasets:
                path = ["calibration", *_where(f"calibration/set/{when}/{name}")[1][2:]]
                _assert_same(_get(cfg, path), ds[()], f"calibration {when}/{name}")
    assert checked > 80  # raw, processed, fits, calibration, protocol, plan, events


def test_every_attribute_is_exported_with_indices_made_one_based(exported: tuple[Path, Path]) -> None:
    """Every attribute but the archive's integrity record (`attribute_sha256`, checked before the export)."""
    archive, out = exported
    files = {p.name: _load(p) for p in sorted(out.glob("*.mat"))}
    with h5py.File(archive, "r") as f:
        for file in files:
            meta = files[file]["meta"]
            for key, value in f.attrs.items():
                if key != ATTRIBUTE_DIGESTS:
                    _assert_same(getattr(meta, key), value, f"{file}: meta.{key}")
                else:
                    assert not hasattr(meta, key)
            assert meta.archive == "archive.h5" and meta.operator == "automatic (--dry-run or --yes)"

        def visit(name: str, obj: h5py.HLObject) -> None:
            if not isinstance(obj, h5py.Group) or not obj.attrs:
                return
            file, fields = _where(name)
            struct = _get(files[file], fields)
            for key, value in obj.attrs.items():
                if key == ATTRIBUTE_DIGESTS:
                    continue
                if "index0" in key:
                    key, value = key.replace("index0", "index1"), value + 1
                _assert_same(getattr(struct, matlab_name(key)), value, f"{name}@{key}")

        f.visititems(visit)
        cfg = f["configurations/config_12/joints/knee_flexion"]
        assert {"transition_index0_on", "transition_index0_off"} <= set(cfg["trials/1/processed"].attrs)
        mat = files["config_12.mat"]
        assert mat["energy_mean_j"] == cfg["energy_loss_j"].attrs["mean_j"]
        assert mat["energy_std_j"] == cfg["energy_loss_j"].attrs["std_j"]
        assert mat["units"].energy_mean_j == "J"
        summary = files["session.mat"]["configurations"].config_12
        assert summary.file == "config_12.mat" and summary.energy_cycles == cfg["energy_loss_j"].shape[0]
        assert files["session.mat"]["protocol_filename"] == f["protocol"].attrs["filename"]


def test_the_one_based_transition_index_finds_the_first_processed_sample(exported: tuple[Path, Path]) -> None:
    """In MATLAB, raw time_s(transition_index1_on) is the first processed time (the transition point)."""
    _, out = exported
    m = _load(out / "config_12.mat")
    for n in (1, 2, 3):
        t = m[f"trial_{n}"]
        index1 = int(t.transition_index1_on)
        assert t.brace_on.time_s[index1 - 1] == t.time_s[0]


def test_numbers_are_double_1d_arrays_columns_and_names_valid(exported: tuple[Path, Path]) -> None:
    archive, out = exported
    logical = {"converged", "diverged", "applicable", "automatic"}  # checklist fields of session.mat
    with h5py.File(archive, "r") as f:  # and every attribute the archive stores as a boolean

        def booleans(_: str, obj: h5py.HLObject) -> None:
            logical.update(k for k, v in obj.attrs.items() if isinstance(v, (bool, np.bool_)))

        f.visititems(booleans)

    def walk(value: Any, path: str) -> None:
        if hasattr(value, "_fieldnames"):
            for name in value._fieldnames:
                assert MATLAB_NAME.match(name), f"{path}.{name}"
                walk(getattr(value, name), f"{path}.{name}")
        elif isinstance(value, np.ndarray) and value.dtype.kind not in "UO":
            leaf = path.rsplit(".", 1)[-1]
            expected = np.uint8 if leaf in logical else np.float64  # scipy reads logical as uint8
            assert value.dtype == expected, f"{path}: {value.dtype}"
            assert value.ndim == 2, path
        elif isinstance(value, np.ndarray) and value.dtype.kind == "O" and value.shape == (1, 1):
            walk(value[0, 0], path)

    for path in out.glob("*.mat"):
        m = _load(path, squeeze=False)
        for name, value in m.items():
            if not name.startswith("__"):
                assert MATLAB_NAME.match(name), name
                walk(value, f"{path.name}:{name}")
    m = _load(out / "config_12.mat", squeeze=False)
    trial = m["trial_1"][0, 0]
    n = trial.brace_on[0, 0].time_s.shape[0]
    assert trial.brace_on[0, 0].time_s.shape == (n, 1)  # 1-D: a column
    iterations = trial.brace_off[0, 0].scaling[0, 0].iteration.shape[0]
    assert trial.brace_off[0, 0].scaling[0, 0].input_range_deg.shape == (iterations, 2)  # as in the archive


def _all_names(f: h5py.File) -> list[str]:
    names: list[str] = []
    f.visit(names.append)
    return names


def _leaves(value: Any, path: str = "") -> dict[str, Any]:
    """Every non-struct value of a loaded .mat variable, by its dotted path."""
    if hasattr(value, "_fieldnames"):
        found: dict[str, Any] = {}
        for name in value._fieldnames:
            found.update(_leaves(getattr(value, name), f"{path}.{name}"))
        return found
    return {path: value}


def _add_comparison(path: Path) -> None:
    """A comparison of configuration 12 with itself, written as the session's compare step writes one."""
    with h5py.File(path, "r+") as f:
        part = f["configurations/config_12/joints/knee_flexion"]
        identity = {"parameter": "rom", "section": "5.7.2", "title": "itself", "configurations": [12, 12]}
        group = f.create_group("comparisons/itself")
        put_attrs(group, "comparison", identity)
        group.attrs["joints"] = np.array(["knee_flexion"], dtype=h5py.string_dtype())
        values = comparison_values([part, part])
        put_attrs(group.create_group("joints/knee_flexion"), "comparison", {**identity, **values})
        seal_attributes(f)


def test_an_archive_of_the_former_layout_exports_the_same_structure(
    exported: tuple[Path, Path], tmp_path: Path
) -> None:
    """One joint, whatever the layout: the archive keyed by joint and the same archive in the layout written
    before (no `joints/` groups) give the same fields with the same values in every file (the configuration,
    its calibration records, the session's calibration and comparisons); the one keyed by joint adds only
    the attributes naming its joint (`joint`, `joints`)."""
    keyed, former = tmp_path / "keyed" / "archive.h5", tmp_path / "former" / "archive.h5"
    keyed.parent.mkdir()
    former.parent.mkdir()
    shutil.copyfile(exported[0], keyed)
    _add_comparison(keyed)
    shutil.copyfile(keyed, former)
    to_former_layout(former)
    export_mat(keyed, keyed.parent / "mat")
    export_mat(former, former.parent / "mat")
    for file in ("config_12.mat", "session.mat"):
        new, old = _load(keyed.parent / "mat" / file), _load(former.parent / "mat" / file)
        variables = sorted(k for k in old if not k.startswith("__"))
        assert sorted(k for k in new if not k.startswith("__")) == variables
        for variable in variables:
            a, b = _leaves(new[variable], variable), _leaves(old[variable], variable)
            assert set(b) <= set(a), (file, sorted(set(b) - set(a)))
            extra = {path.rsplit(".", 1)[-1] for path in set(a) - set(b)}
            assert extra <= {"joint", "joints"}, (file, sorted(set(a) - set(b)))
            for path, value in b.items():
                _assert_same(a[path], value, f"{file}: {path}")


def test_old_archives_transition_index_and_big_integers(exported: tuple[Path, Path], tmp_path: Path) -> None:
    """An archive written before groups were keyed by joint, before the `_index0` rename and the
    fixed-length text is exported the same; a seed beyond 2**53 stays exact."""
    archive, out = exported
    old = tmp_path / "old.h5"
    shutil.copyfile(archive, old)
    to_former_layout(old)
    with h5py.File(old, "r+") as f:
        g = f["configurations/config_12/trials/1/processed"]
        g.attrs["transition_index_on"] = g.attrs.pop("transition_index0_on")
        f.attrs["seed"] = np.int64(2**60 + 1)
        del f.attrs["dataset_checksums"]  # archives of that time had no checksums
        del f.attrs[ATTRIBUTE_MARKER]
        for obj in [f, *(f[name] for name in _all_names(f))]:
            obj.attrs.pop(ATTRIBUTE_DIGESTS, None)
        text = f["protocol"][()].decode()
        del f["protocol"]  # text as variable-length strings, as archives were written before
        f.create_dataset("protocol", data=text, dtype=h5py.string_dtype())
        events = [e.decode() for e in f["session/events"][()]]
        del f["session/events"]
        f["session"].create_dataset("events", data=events, dtype=h5py.string_dtype())
    export_mat(old, tmp_path / "mat")
    session = _load(tmp_path / "mat" / "session.mat")
    assert session["protocol"] == text and list(session["session"].events) == events
    m = _load(tmp_path / "mat" / "config_12.mat")
    assert m["trial_1"].transition_index1_on == _load(out / "config_12.mat")["trial_1"].transition_index1_on
    assert isinstance(m["meta"].seed, int) and m["meta"].seed == 2**60 + 1  # int64, not a rounded double


def test_matlab_names() -> None:
    assert matlab_name("config_12") == "config_12"
    assert matlab_name("1", "trial") == "trial_1"
    assert matlab_name("_1", "trial") == "trial_1"
    assert matlab_name("check__rom__brace-off") == "check__rom__brace_off"
    assert matlab_name("x" * 80) == "x" * 63
    struct: dict[str, Any] = {}
    assert [put_field(struct, n, 0) for n in ("a-b", "a_b", "a__b", "a.b")] == [
        "a_b",
        "a_b_2",
        "a__b",
        "a__b_2",
    ]
    # a factor quantity attribute `<factor>.<quantity>`: the dot becomes a double underscore
    assert matlab_name("friction.friction_nm") == "friction__friction_nm"
    assert matlab_name("brace_rom.range_deg") == "brace_rom__range_deg"


@pytest.mark.parametrize("fault", ["foreign", "not_a_directory", "units_conflict", "compound"])
def test_bad_input_exits_2_with_one_clear_line(
    fault: str, exported: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    archive, _ = exported
    target = tmp_path / "mat"
    bad = tmp_path / "archive.h5"
    shutil.copyfile(archive, bad)
    expected = {
        "foreign": "not a protocol-runner archive",
        "not_a_directory": "--export-mat: cannot create",
        "units_conflict": "has units 'rad' but",
        "compound": "unexpected data type",  # refused by the archive check before the export
    }[fault]
    with h5py.File(bad, "r+") as f:
        if fault == "foreign":
            del f.attrs["protocol_sha256"]
        elif fault == "units_conflict":
            ds = f["configurations/config_12/trials/2/brace_on/joints/knee_flexion/angle_deg"]
            ds.attrs["units"] = "rad"
            seal_attributes_of(ds, ["units"])  # as a writer would have recorded it: not a damaged file
        elif fault == "compound":
            f["configurations/config_12/trials/1/brace_on"].create_dataset(
                "odd", data=np.zeros(2, dtype=[("a", "f8"), ("b", "i4")])
            )
    if fault == "not_a_directory":
        target.write_text("a file")
    assert main(["--report", str(bad), "--export-mat", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and "Traceback" not in err and len(err.splitlines()) == 1, err
    if fault != "not_a_directory":
        assert not list(target.glob("*.partial"))
