"""Facts about calibration look-up tables (thesis §2.5): loading, mapping, inversion, building."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.calibration import (
    CalibrationTable,
    build_table_from_observations,
    build_torque_table_from_observations,
    load_calibration_table,
    write_calibration_table,
)
from protocol_runner.hardware.calibration_build import main

SHIPPED = Path(__file__).resolve().parents[2] / "protocols" / "calibration"


def _write(tmp_path: Path, text: str, name: str = "table.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_table_interpolates_linearly_between_points() -> None:
    table = CalibrationTable(np.array([0.0, 10.0, 20.0]), np.array([0.0, 20.0, 25.0]), "a", "b")
    np.testing.assert_allclose(table(np.array([5.0, 10.0, 15.0])), [10.0, 20.0, 22.5])


def test_table_extrapolates_with_the_end_segments() -> None:
    table = CalibrationTable(np.array([0.0, 10.0, 20.0]), np.array([0.0, 20.0, 25.0]), "a", "b")
    np.testing.assert_allclose(table(np.array([-1.0, 22.0])), [-2.0, 26.0])


def test_inverse_undoes_the_table_including_extrapolation() -> None:
    table = CalibrationTable(np.array([0.0, 10.0, 20.0]), np.array([3.0, 1.0, -4.0]), "a", "b")
    x = np.linspace(-5.0, 25.0, 61)
    inverse = table.inverse()
    assert (inverse.x_name, inverse.y_name) == ("b", "a")
    np.testing.assert_allclose(inverse(table(x)), x, atol=1e-12)


@pytest.mark.parametrize(
    ("x", "y", "message"),
    [
        ([0.0], [0.0], "at least 2"),
        ([0.0, np.nan], [0.0, 1.0], "NaN"),
        ([0.0, 0.0], [0.0, 1.0], "strictly increasing"),
        ([0.0, 1.0, 2.0], [0.0, 1.0, 0.5], "strictly monotonic"),
    ],
)
def test_invalid_tables_are_rejected(x: list[float], y: list[float], message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        CalibrationTable(np.array(x), np.array(y), "a", "b")


def test_table_arrays_are_read_only() -> None:
    table = CalibrationTable(np.array([0.0, 1.0]), np.array([0.0, 1.0]), "a", "b")
    with pytest.raises(ValueError, match="read-only"):
        table.x[0] = 5.0


def test_load_reads_comments_header_and_rows(tmp_path: Path) -> None:
    path = _write(
        tmp_path, "# maps real to input\n#  units: deg\n\nreal_deg,input_deg\n0,1\n10, 12.5\n20,22\n"
    )
    table = load_calibration_table(path)
    assert (table.x_name, table.y_name, table.source) == ("real_deg", "input_deg", str(path))
    np.testing.assert_array_equal(table.x, [0.0, 10.0, 20.0])
    np.testing.assert_array_equal(table.y, [1.0, 12.5, 22.0])


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("# c\nx_deg,y_deg\n0,0\n1,abc\n", 4, "not a number"),
        ("x_deg,y_deg\n0,0\n1,nan\n", 3, "finite"),
        ("x_deg,y_deg\n0,0\n2,1\n1,2\n", 4, "strictly increasing"),
        ("x_deg,y_deg\n0,0\n1,2\n2,1\n", 4, "strictly monotonic"),
        ("x_deg,y_deg\n0,0\n1,0\n", 3, "strictly monotonic"),
        ("0,0\n1,1\n", 1, "header row"),
        ("x_deg,y_deg\n0,0,0\n", 2, "2 comma-separated columns"),
    ],
)
def test_load_errors_name_file_and_line(tmp_path: Path, text: str, line: int, message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(InvalidInput, match=message) as info:
        load_calibration_table(path)
    assert f"{path}, line {line}" in str(info.value)


def test_load_errors_for_too_few_rows_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InvalidInput, match="at least 2 data rows"):
        load_calibration_table(_write(tmp_path, "x_deg,y_deg\n0,0\n"))
    with pytest.raises(InvalidInput, match="no header"):
        load_calibration_table(_write(tmp_path, "# only a comment\n"))
    with pytest.raises(InvalidInput, match="not found"):
        load_calibration_table(tmp_path / "missing.csv")


@settings(max_examples=40)
@given(
    steps=st.lists(st.floats(min_value=0.01, max_value=50.0), min_size=1, max_size=30),
    slopes=st.lists(st.floats(min_value=0.01, max_value=10.0), min_size=30, max_size=30),
    start=st.floats(min_value=-100.0, max_value=100.0),
)
def test_write_then_load_round_trips_exactly(
    tmp_path_factory: pytest.TempPathFactory, steps: list[float], slopes: list[float], start: float
) -> None:
    x = start + np.concatenate([[0.0], np.cumsum(steps)])
    y = np.concatenate([[0.0], np.cumsum(np.array(steps) * np.array(slopes[: len(steps)]))])
    table = CalibrationTable(x, y, "output_deg", "real_deg")
    path = tmp_path_factory.mktemp("rt") / "t.csv"
    write_calibration_table(path, table, "line one\nline two")
    loaded = load_calibration_table(path)
    np.testing.assert_array_equal(loaded.x, table.x)
    np.testing.assert_array_equal(loaded.y, table.y)
    assert path.read_text(encoding="utf-8").startswith("# line one\n# line two\noutput_deg,real_deg\n")


@pytest.mark.parametrize(
    ("name", "columns", "span"),
    [
        ("knee_command.csv", ("real_deg", "input_deg"), (0.0, 130.0)),
        ("knee_angle.csv", ("output_deg", "real_deg"), (0.0, 130.0)),
        ("knee_torque.csv", ("output_nm", "real_nm"), (-84.8, 84.8)),
    ],
)
def test_shipped_knee_tables(name: str, columns: tuple[str, str], span: tuple[float, float]) -> None:
    """Shipped tables load, map the stated quantities, span the joint's Eq 1-3 range end to end (so a
    full-range command stays inside ±10 V), are increasing, mildly nonlinear (a few units at most) and
    say in their header that they are illustrative."""
    path = SHIPPED / name
    table = load_calibration_table(path)
    assert (table.x_name, table.y_name) == columns
    assert (table.x[0], table.x[-1]) == span
    assert (table.y[0], table.y[-1]) == span
    assert table.y[-1] > table.y[0]
    deviation = np.abs(table.y - table.x)
    assert 0.5 < deviation.max() < 5.0
    header = "".join(line for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("#"))
    assert "ILLUSTRATIVE" in header


def test_build_tables_invert_the_observed_relations() -> None:
    """§2.5.1: command table maps real -> input, telemetry table maps output -> real."""
    input_deg = np.array([0.0, 30.0, 60.0, 90.0, 120.0])
    real_deg = input_deg + np.array([2.0, 1.0, 0.0, -1.0, -2.5])
    output_deg = real_deg + np.array([-1.0, 0.5, 0.0, 0.5, 1.0])
    command, angle = build_table_from_observations(input_deg, real_deg, output_deg)
    assert (command.x_name, command.y_name) == ("real_deg", "input_deg")
    assert (angle.x_name, angle.y_name) == ("output_deg", "real_deg")
    np.testing.assert_allclose(command(real_deg), input_deg)
    np.testing.assert_allclose(angle(output_deg), real_deg)


def test_build_averages_repeated_observations_and_sorts() -> None:
    command, _ = build_table_from_observations([90.0, 0.0, 0.0], [88.0, 1.0, 1.0], [88.0, 1.0, 1.0])
    np.testing.assert_array_equal(command.x, [1.0, 88.0])
    np.testing.assert_array_equal(command.y, [0.0, 90.0])
    command, angle = build_table_from_observations([0.0, 10.0, 0.0], [1.0, 11.0, 2.0], [1.0, 11.0, 1.0])
    np.testing.assert_array_equal(command.x, [1.5, 11.0])
    np.testing.assert_array_equal(command.y, [0.0, 10.0])
    np.testing.assert_array_equal(angle.x, [1.0, 11.0])
    np.testing.assert_array_equal(angle.y, [1.5, 11.0])


def test_build_rejects_non_invertible_observations() -> None:
    with pytest.raises(InvalidInput, match="not strictly monotonic"):
        build_table_from_observations([0.0, 10.0, 20.0], [0.0, 12.0, 9.0], [0.0, 10.0, 20.0])
    with pytest.raises(InvalidInput, match="same number"):
        build_table_from_observations([0.0, 10.0], [0.0], [0.0, 10.0])


def test_build_torque_table() -> None:
    table = build_torque_table_from_observations([-50.0, 0.0, 50.0], [-48.0, 0.5, 51.0])
    assert (table.x_name, table.y_name) == ("output_nm", "real_nm")
    np.testing.assert_allclose(table([-48.0, 0.5, 51.0]), [-50.0, 0.0, 50.0])


def test_cli_builds_tables_that_load(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obs = _write(
        tmp_path,
        "# knee calibration, 2026-11-21\ninput_deg,real_deg,output_deg\n"
        "0,1,0\n45,44,45.5\n90,88,89\n130,129,130\n",
        name="knee_observations.csv",
    )
    out_dir = tmp_path / "tables"
    assert main(["build", str(obs), "--out-dir", str(out_dir)]) == 0
    written = capsys.readouterr().out.split()
    assert written == [str(out_dir / "knee_command.csv"), str(out_dir / "knee_angle.csv")]
    command = load_calibration_table(out_dir / "knee_command.csv")
    assert float(command(88.0)) == pytest.approx(90.0)


def test_cli_reports_bad_input_without_traceback(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obs = _write(tmp_path, "a,b\n1,2\n", name="obs.csv")
    assert main(["build", str(obs), "--out-dir", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: observations") and "input_deg" in err and "Traceback" not in err


def test_module_runs_with_python_dash_m() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "protocol_runner.hardware.calibration_build", "build", "--help"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0
    assert "--out-dir" in proc.stdout and "real_deg -> input_deg" in proc.stdout


@settings(max_examples=60)
@given(
    steps=st.lists(st.floats(min_value=0.05, max_value=20.0), min_size=1, max_size=20),
    slopes=st.lists(st.floats(min_value=0.1, max_value=5.0), min_size=20, max_size=20),
    decreasing=st.booleans(),
    probe=st.floats(min_value=-0.5, max_value=1.5),
)
def test_inverse_round_trip_property(
    steps: list[float], slopes: list[float], decreasing: bool, probe: float
) -> None:
    """For any strictly monotonic table, inverse(table(x)) == x, inside and outside the table's span."""
    x = np.concatenate([[0.0], np.cumsum(steps)])
    dy = np.array(steps) * np.array(slopes[: len(steps)]) * (-1.0 if decreasing else 1.0)
    table = CalibrationTable(x, np.concatenate([[0.0], np.cumsum(dy)]), "a", "b")
    value = x[0] + probe * (x[-1] - x[0])
    assert float(table.inverse()(table(value))) == pytest.approx(value, abs=1e-9)
