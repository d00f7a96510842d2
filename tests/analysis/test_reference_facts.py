"""Facts about reading an external torque-angle dataset (analysis/reference.py, the EMU data of thesis
§5.6): the columns found by name in CSV or .mat, at least two samples of each, and every defect reported as
`InvalidInput` naming the file (and the line, for CSV) instead of a traceback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from protocol_runner.analysis.reference import load_reference_dataset
from protocol_runner.errors import InvalidInput


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_csv_columns_are_found_by_name_in_any_order_and_case(tmp_path: Path) -> None:
    path = write(
        tmp_path / "emu_knee.csv",
        "# EMU knee, suited\nTime_s,Torque_Nm,Joint_Angle_deg,torque_std\n0,1.5,10,9\n1,2.5,20,9\n2,3.5,35,9\n",
    )
    ref = load_reference_dataset(path)
    np.testing.assert_array_equal(ref.angle_deg, [10.0, 20.0, 35.0])
    np.testing.assert_array_equal(ref.torque_nm, [1.5, 2.5, 3.5])  # the first "torque" column
    assert ref.title == "emu_knee" and ref.source == str(path)
    assert load_reference_dataset(path, title="EMU suited knee").title == "EMU suited knee"
    with pytest.raises(ValueError):  # the dataset is read-only: nobody edits the reference by accident
        ref.angle_deg[0] = 0.0


@pytest.mark.parametrize("rows", [2, 3])
def test_two_samples_are_enough_and_one_is_not(tmp_path: Path, rows: int) -> None:
    body = "".join(f"{10 * k},{k}\n" for k in range(rows))
    ref = load_reference_dataset(write(tmp_path / "r.csv", "angle_deg,torque_nm\n" + body))
    assert ref.angle_deg.size == rows and ref.torque_nm.size == rows
    with pytest.raises(
        InvalidInput, match=r"r1\.csv: angle and torque columns must have the same length >= 2"
    ):
        load_reference_dataset(write(tmp_path / "r1.csv", "angle_deg,torque_nm\n10,1\n"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", r"bad\.csv has no header row"),
        ("# only a comment\n", r"bad\.csv has no header row"),
        (
            "time_s,angle_deg\n0,10\n1,20\n",
            r"bad\.csv, line 1: the header must name an angle column and a torque",
        ),
        (
            "time_s,torque_nm\n0,10\n1,20\n",
            r"bad\.csv, line 1: the header must name an angle column and a torque",
        ),
        ("# c\nangle_deg,torque_nm\n10,1\n20,x\n", r"bad\.csv, line 4: not a number row \('20,x'\)"),
        ("angle_deg,torque_nm\n10,1\n20\n30,3\n", r"bad\.csv, line 3: not a number row \('20'\)"),
    ],
)
def test_a_csv_defect_names_the_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        load_reference_dataset(write(tmp_path / "bad.csv", text))


def test_an_unreadable_csv_is_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    binary = tmp_path / "latin.csv"
    binary.write_bytes(b"angle_deg,torque_nm\n\xff\xfe,1\n")
    with pytest.raises(InvalidInput, match=r"latin\.csv: cannot read it"):
        load_reference_dataset(binary)

    def denied(self: Path, *args: object, **kwargs: object) -> str:
        raise PermissionError(13, "Permission denied", str(self))

    path = write(tmp_path / "locked.csv", "angle_deg,torque_nm\n10,1\n20,2\n")
    monkeypatch.setattr(Path, "open", denied)
    with pytest.raises(InvalidInput, match=r"locked\.csv: cannot read it .*Permission denied"):
        load_reference_dataset(path)


@pytest.mark.parametrize("name", ["emu.txt", "emu.bin", "emu.xlsx", "emu"])
def test_only_csv_and_mat_are_read(tmp_path: Path, name: str) -> None:
    with pytest.raises(InvalidInput, match="unsupported format"):
        load_reference_dataset(write(tmp_path / name, "angle_deg,torque_nm\n10,1\n20,2\n"))


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(InvalidInput, match=r"nowhere\.csv does not exist"):
        load_reference_dataset(tmp_path / "nowhere.csv")


def test_mat_variables_are_found_by_name_and_flattened(tmp_path: Path) -> None:
    """MATLAB stores vectors as 1xN or Nx1 matrices; the suffix may be upper case."""
    path = tmp_path / "EMU.MAT"
    angle = np.array([10.0, 20.0, 30.0, 40.0])
    savemat(str(path), {"Angle_deg": angle.reshape(-1, 1), "TORQUE": 0.1 * angle.reshape(1, -1), "t": angle})
    ref = load_reference_dataset(path)
    np.testing.assert_array_equal(ref.angle_deg, angle)
    np.testing.assert_allclose(ref.torque_nm, 0.1 * angle)
    assert ref.title == "EMU"


@pytest.mark.parametrize(("n_angle", "n_torque"), [(3, 4), (4, 3), (1, 1)])
def test_mat_columns_of_unequal_or_too_short_length_are_refused(
    tmp_path: Path, n_angle: int, n_torque: int
) -> None:
    path = tmp_path / "emu.mat"
    savemat(str(path), {"angle": np.arange(float(n_angle)), "torque": np.arange(float(n_torque))})
    with pytest.raises(InvalidInput, match=f"same length >= 2 \\(got {n_angle} and {n_torque}\\)"):
        load_reference_dataset(path)


def test_mat_defects_are_reported_not_raised(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.mat"
    garbage.write_bytes(b"not a MATLAB file at all, " * 8)
    empty = tmp_path / "empty.mat"
    empty.write_bytes(b"")
    for path in (garbage, empty):
        with pytest.raises(InvalidInput, match=rf"{path.name} is not a readable MATLAB \.mat file"):
            load_reference_dataset(path)
    savemat(str(tmp_path / "names.mat"), {"theta": np.arange(3.0), "torque": np.arange(3.0)})
    with pytest.raises(InvalidInput, match=r"needs variables named angle\* and torque\*"):
        load_reference_dataset(tmp_path / "names.mat")
    savemat(str(tmp_path / "names2.mat"), {"angle": np.arange(3.0), "moment": np.arange(3.0)})
    with pytest.raises(InvalidInput, match=r"needs variables named angle\* and torque\*"):
        load_reference_dataset(tmp_path / "names2.mat")
    savemat(str(tmp_path / "text.mat"), {"angle": "abc", "torque": np.arange(3.0)})
    savemat(str(tmp_path / "struct.mat"), {"angle": np.arange(3.0), "torque": {"a": 1.0}})
    for name in ("text.mat", "struct.mat"):
        with pytest.raises(InvalidInput, match=r"angle/torque are not numeric"):
            load_reference_dataset(tmp_path / name)
    savemat(str(tmp_path / "nan.mat"), {"angle": np.array([1.0, np.nan]), "torque": np.arange(2.0)})
    with pytest.raises(InvalidInput, match="must be finite numbers"):
        load_reference_dataset(tmp_path / "nan.mat")


def test_a_dataset_of_thousands_of_samples_is_read_whole(tmp_path: Path) -> None:
    angle = np.linspace(5.0, 110.0, 2000)
    torque = 0.3 * (angle - 20.0)
    savemat(str(tmp_path / "emu.mat"), {"angle_deg": angle, "torque_nm": torque})
    rows = "".join(f"{float(a)!r},{float(t)!r}\n" for a, t in zip(angle, torque, strict=True))
    write(tmp_path / "emu.csv", "angle_deg,torque_nm\n" + rows)
    for name in ("emu.mat", "emu.csv"):
        ref = load_reference_dataset(tmp_path / name)
        np.testing.assert_array_equal(ref.angle_deg, angle)
        np.testing.assert_array_equal(ref.torque_nm, torque)
