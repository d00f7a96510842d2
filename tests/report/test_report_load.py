"""Reading archives into ReportData: contents, summaries, and clear errors for bad files."""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.analysis.reference import load_reference_dataset
from protocol_runner.archive.verify import validate_archive
from protocol_runner.errors import InvalidInput
from protocol_runner.report.h5read import MAX_PLOT_POINTS, decimate_for_plot
from protocol_runner.report.load import load_report_data
from tests.report.report_archive_builder import (
    FACTORS,
    FRICTION_ENERGY_J,
    ArchiveSpec,
    ConfigSpec,
    small_spec,
    write_archive,
)


def test_root_attributes_and_session_log_are_read(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    s = data.session
    assert (s.protocol_name, s.protocol_sha256, s.mode, s.seed) == ("knee_synthetic", "ab" * 32, "dry-run", 7)
    assert s.status == "complete" and s.complete
    assert s.only == (4, 5, 6, 7)
    assert [e.kind for e in s.interruptions] == ["interrupted", "resumed"]
    assert s.checklists[0].step_id == "brace_rom:fit_brace"
    assert s.checklists[0].items == ("Set the stops to 40-90 deg", "Tighten the 8 mm bolt to 11 ft-lb")
    assert s.checklists[0].automatic is True


def test_configurations_are_sorted_with_settings_trials_and_fits(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    assert [c.key for c in data.configurations] == [4, 5, 6, 7]
    cfg = data.configuration(7)
    assert cfg is not None
    assert cfg.settings.factor_names() == FACTORS
    assert cfg.level("friction") == "3" and cfg.quantity("friction", "friction_nm") == pytest.approx(6.25)
    assert cfg.quantity("brace_rom", "range_deg") == (0.0, 130.0)
    assert cfg.settings.trajectory == "sine"
    brake = cfg.settings.element("brake")
    assert brake is not None and brake.type == "coulomb_brake" and dict(brake.params)["torque_nm"] == 6.25
    assert [t.number for t in cfg.trials] == [1, 2]
    assert all(t.processed is not None for t in cfg.trials)
    # raw recordings are read for the plotted (first) trial only
    assert cfg.trials[0].brace_on is not None and cfg.trials[0].brace_off is not None
    assert cfg.trials[1].brace_on is None and cfg.trials[1].recorded
    assert cfg.bouc_wen is not None and len(cfg.bouc_wen.beta) == 6
    fit = cfg.element_fit
    assert fit is not None and fit.applicable and fit.target == "midline"
    assert fit.parameters == (("springs.zero_offset_deg", pytest.approx(20.7)),)
    assert [e.name for e in fit.elements] == ["springs"]
    assert dict(fit.elements[0].params)["zero_offset_deg"] == 20.7


def test_energy_per_cycle_matches_the_elliptic_loops_written(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    for cfg in data.configurations:
        # 2 % spread per cycle around the ellipse's energy pi^2 a b / 180 (Eq 10-12)
        assert cfg.energy_mean_j == pytest.approx(FRICTION_ENERGY_J[cfg.key], rel=0.03)
        assert 0.0 < cfg.energy_std_j < 0.1 * FRICTION_ENERGY_J[cfg.key]
        assert set(cfg.energy_cycle_trial.tolist()) == {1.0, 2.0}


def test_angle_range_and_slope_come_from_the_full_processed_data(small_archive: Path) -> None:
    cfg = load_report_data(small_archive).configuration(5)
    assert cfg is not None
    assert cfg.angle_min_deg == pytest.approx(5.0, abs=0.01)
    assert cfg.angle_max_deg == pytest.approx(109.0, abs=0.01)
    # over whole cycles the cos term of the ellipse is orthogonal to the angle: the slope is the spring's
    slopes = [t.processed.slope_nm_per_deg for t in cfg.trials if t.processed is not None]
    assert slopes and slopes == pytest.approx([0.3] * len(slopes), rel=0.02)


def test_plot_series_are_decimated_to_the_point_budget(small_archive: Path) -> None:
    cfg = load_report_data(small_archive).configuration(4)
    assert cfg is not None and cfg.trials[0].processed is not None
    assert 0 < cfg.trials[0].processed.angle_deg.size <= MAX_PLOT_POINTS
    assert not cfg.trials[0].processed.angle_deg.flags.writeable


def test_decimate_keeps_endpoints_spacing_and_budget() -> None:
    x = np.arange(65_000, dtype=float)
    d = decimate_for_plot(x, 2000)
    assert d.size <= 2000 and d[0] == 0.0
    assert np.all(np.diff(d) == np.diff(d)[0])
    assert decimate_for_plot(x[:10], 2000).size == 10


def test_session_directory_is_accepted(small_archive: Path) -> None:
    assert load_report_data(small_archive.parent).session.archive_path == str(small_archive)


def test_parallel_and_serial_loading_agree(small_archive: Path) -> None:
    serial = load_report_data(small_archive, workers=1)
    parallel = load_report_data(small_archive, workers=2)
    assert [c.key for c in serial.configurations] == [c.key for c in parallel.configurations]
    for a, b in zip(serial.configurations, parallel.configurations, strict=True):
        assert np.array_equal(a.energy_loss_j, b.energy_loss_j)
        assert a.angle_max_deg == b.angle_max_deg


def test_unfinished_session_loads_and_is_marked_incomplete(tmp_path: Path) -> None:
    spec = small_spec(status="incomplete")
    spec.configs[-1].status = "not run"
    data = load_report_data(write_archive(tmp_path / "archive.h5", spec))
    assert data.session.status == "incomplete" and not data.session.complete
    last = data.configuration(7)
    assert last is not None and last.status == "not run" and last.trials == ()
    assert math.isnan(last.energy_mean_j) and math.isnan(last.angle_max_deg)


def test_archive_without_comparisons_has_none_and_says_so(tmp_path: Path) -> None:
    data = load_report_data(write_archive(tmp_path / "archive.h5", small_spec(comparisons=False)))
    assert data.comparisons == ()
    assert any("declares no comparisons" in note for note in data.notes)


def test_an_interrupted_session_whose_comparisons_did_not_run_does_not_say_none_are_declared(
    tmp_path: Path,
) -> None:
    spec = small_spec(comparisons=False, status="incomplete")
    spec.protocol_text = (
        "name: knee_synthetic\njoint: knee_flexion\nreport:\n  comparisons:\n"
        "    - {name: speed, parameter: speed, configurations: [3, 5]}\n"
        "    - {name: friction, parameter: friction, configurations: [3, 7]}\n"
    )
    data = load_report_data(write_archive(tmp_path / "archive.h5", spec))
    assert data.comparisons == ()
    assert not any("declares no comparisons" in note for note in data.notes), data.notes
    assert any(
        "declares 2 comparisons, none made yet in this session (status incomplete)" in note
        for note in data.notes
    ), data.notes


# ----------------------------------------------------------------------------------------- bad inputs


def test_missing_file_is_invalid_input(tmp_path: Path) -> None:
    with pytest.raises(InvalidInput, match="does not exist"):
        load_report_data(tmp_path / "nope.h5")


def test_directory_without_archive_is_invalid_input(tmp_path: Path) -> None:
    with pytest.raises(InvalidInput, match=r"without an archive\.h5"):
        load_report_data(tmp_path)


def test_text_file_is_not_an_hdf5_file(tmp_path: Path) -> None:
    path = tmp_path / "archive.h5"
    path.write_text("name: knee\n")
    with pytest.raises(InvalidInput, match=r"archive\.h5 is not an HDF5 file"):
        load_report_data(path)


def test_truncated_archive_is_reported_as_truncated_or_corrupt(tmp_path: Path) -> None:
    path = write_archive(tmp_path / "archive.h5", small_spec(duration_s=8.0))
    size = path.stat().st_size
    with path.open("r+b") as fh:
        fh.truncate(size // 2)
    with pytest.raises(InvalidInput, match=r"archive\.h5 is truncated or corrupt; "):
        load_report_data(path)


def test_foreign_hdf5_file_is_not_a_protocol_runner_archive(tmp_path: Path) -> None:
    path = tmp_path / "foreign.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("x", data=np.arange(3))
        f.attrs["creator"] = "someone else"
    with pytest.raises(
        InvalidInput,
        match=r"foreign\.h5 is not a protocol-runner archive: missing root attribute protocol_sha256",
    ):
        load_report_data(path)


def test_archive_missing_configurations_names_the_group(tmp_path: Path) -> None:
    path = write_archive(tmp_path / "archive.h5", small_spec(duration_s=4.0))
    with h5py.File(path, "a") as f:
        del f["configurations"]
    with pytest.raises(InvalidInput, match="missing group /configurations"):
        load_report_data(path)


# ------------------------------------------------------------------------------------ reference data


def test_reference_csv_is_read_by_column_names(tmp_path: Path) -> None:
    path = tmp_path / "emu.csv"
    path.write_text("# Schmidt EMU knee\ntime_s,angle_deg,torque_nm\n0,10,1.5\n0.1,20,2.5\n0.2,30,3.0\n")
    ref = load_reference_dataset(path)
    assert ref.angle_deg.tolist() == [10.0, 20.0, 30.0]
    assert ref.torque_nm.tolist() == [1.5, 2.5, 3.0]


def test_reference_csv_with_a_bad_row_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "emu.csv"
    path.write_text("angle,torque\n10,1\n20,oops\n")
    with pytest.raises(InvalidInput, match="line 3"):
        load_reference_dataset(path)


def test_reference_csv_without_angle_column_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "emu.csv"
    path.write_text("x,torque\n10,1\n20,2\n")
    with pytest.raises(InvalidInput, match="angle column"):
        load_reference_dataset(path)


def test_reference_mat_is_read_by_variable_names(tmp_path: Path) -> None:
    from scipy.io import savemat

    path = tmp_path / "correcteddata.mat"
    savemat(
        str(path), {"angleKnee": np.array([[5.0], [50.0], [95.0]]), "torqueKnee": np.array([0.5, 4.0, 9.0])}
    )
    ref = load_reference_dataset(path)
    assert ref.angle_deg.tolist() == [5.0, 50.0, 95.0] and ref.torque_nm.tolist() == [0.5, 4.0, 9.0]
    assert ref.title == "correcteddata"


def test_reference_of_unknown_format_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "emu.xlsx"
    path.write_bytes(b"PK")
    with pytest.raises(InvalidInput, match="unsupported format"):
        load_reference_dataset(path)


def test_reference_groups_in_the_archive_are_read(tmp_path: Path) -> None:
    spec = ArchiveSpec(configs=[ConfigSpec(key=27, n_trials=1)], duration_s=8.0, reference=True)
    data = load_report_data(write_archive(tmp_path / "archive.h5", spec))
    assert [r.title for r in data.references] == ["Schmidt EMU data"]
    assert data.references[0].angle_deg.size == 300


def test_validate_archive_accepts_a_good_archive_and_rejects_a_foreign_one(
    small_archive: Path, tmp_path: Path
) -> None:
    assert validate_archive(small_archive.parent) == small_archive
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f.attrs["creator"] = "someone else"
    with pytest.raises(InvalidInput, match="missing root attribute protocol_sha256"):
        validate_archive(foreign)
    truncated = tmp_path / "archive.h5"
    truncated.write_bytes(small_archive.read_bytes()[:4096])
    with pytest.raises(InvalidInput, match="is truncated or corrupt"):
        validate_archive(truncated)
