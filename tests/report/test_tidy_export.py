"""`--export`: tidy CSV tables whose rows reproduce the report's trial-level intervals."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from protocol_runner.cli import main
from protocol_runner.report.headline import configuration_stats
from protocol_runner.report.load import load_report_data
from protocol_runner.report.tidy import CYCLE_COLUMNS, export_tables


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def tables(small_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tables")
    export_tables(small_archive, out)
    return out


def test_cycles_csv_has_one_row_per_archived_cycle_with_units_in_the_names(
    small_archive: Path, tables: Path
) -> None:
    rows = _rows(tables / "cycles.csv")
    assert tuple(rows[0].keys()) == CYCLE_COLUMNS
    data = load_report_data(small_archive, workers=1)
    for cfg in data.configurations:
        own = [r for r in rows if int(r["configuration"]) == cfg.key]
        assert [float(r["energy_j"]) for r in own] == pytest.approx(cfg.energy_loss_j.tolist())
        assert [int(r["trial"]) for r in own] == cfg.energy_cycle_trial.tolist()
        for r in own:  # the cycle's own angle range lies inside the configuration's (or is left empty)
            if r["angle_min_deg"] == "":
                assert r["angle_max_deg"] == r["torque_peak_nm"] == ""
                continue
            assert cfg.angle_min_deg - 1e-6 <= float(r["angle_min_deg"]) < float(r["angle_max_deg"])
            assert float(r["angle_max_deg"]) <= cfg.angle_max_deg + 1e-6
            assert float(r["torque_peak_nm"]) > 0


def test_trials_and_configurations_reproduce_the_report_intervals(
    small_archive: Path, small_report: str, tables: Path
) -> None:
    trials = _rows(tables / "trials.csv")
    configs = {int(r["configuration"]): r for r in _rows(tables / "configurations.csv")}
    data = load_report_data(small_archive, workers=1)
    for cfg in data.configurations:
        means = np.array([float(r["energy_mean_j"]) for r in trials if int(r["configuration"]) == cfg.key])
        row = configs[cfg.key]
        # the configuration row follows from the trial rows (t-interval over trial means) ...
        low, high = stats.t.interval(0.95, means.size - 1, loc=means.mean(), scale=stats.sem(means))
        assert float(row["energy_mean_j"]) == pytest.approx(means.mean(), rel=1e-12)
        assert float(row["energy_ci95_low_j"]) == pytest.approx(low, rel=1e-9)
        assert float(row["energy_ci95_high_j"]) == pytest.approx(high, rel=1e-9)
        assert int(row["trials"]) == means.size
        # ... and equals what the report's summary prints
        s = configuration_stats(cfg)
        cell = re.search(rf'<tr id="headline-{cfg.key}".*?</tr>', small_report, re.S)
        assert cell is not None
        assert f"[{s.energy.low:.2f}, {s.energy.high:.2f}]" in cell.group(0)
        assert (
            f"[{float(row['energy_ci95_low_j']):.2f}, {float(row['energy_ci95_high_j']):.2f}]"
            in cell.group(0)
        )
        # one column per declared factor (its level) and per factor quantity, lists joined with ";"
        assert row["friction"] == cfg.level("friction")
        assert row["friction.friction_nm"] == repr(cfg.quantity("friction", "friction_nm"))
        assert row["brace_rom.range_deg"] == "0.0;130.0"


def test_cli_export_writes_the_six_tables(small_archive: Path, tmp_path: Path) -> None:
    assert main(["--export", str(small_archive), "--output", str(tmp_path / "out")]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "configurations.csv",
        "cycles.csv",
        "elements.csv",
        "models.csv",
        "predictions.csv",
        "trials.csv",
    ]


def test_cli_export_of_a_missing_archive_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--export", str(tmp_path / "nothing.h5")]) == 2
    err = capsys.readouterr().err
    assert "nothing.h5" in err and "Traceback" not in err


def test_cli_export_into_a_file_exits_2(
    small_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "afile"
    target.write_text("x")
    assert main(["--export", str(small_archive), "--output", str(target)]) == 2
    assert "is a file; give a directory" in capsys.readouterr().err


def test_configurations_csv_has_a_column_per_declared_factor_and_quantity_in_order(tables: Path) -> None:
    from tests.report.report_archive_builder import FACTORS, factor_settings

    with (tables / "configurations.csv").open(encoding="utf-8", newline="") as fh:
        header = next(csv.reader(fh))
    expected = []
    for factor in FACTORS:  # declaration order, each level column followed by its quantities
        expected.append(factor)
        expected.extend(f"{factor}.{q}" for q in factor_settings(4)[factor] if q != "level")
    assert header[:5] == ["configuration", "set", "joint", "profile", "trajectory"]
    assert header[5 : 5 + len(expected)] == expected
    assert header[5 + len(expected)] == "trials"


def test_every_table_names_the_one_joint_of_a_single_joint_archive(tables: Path) -> None:
    for name in ("cycles.csv", "trials.csv", "configurations.csv"):
        rows = _rows(tables / name)
        assert rows and {r["joint"] for r in rows} == {"knee_flexion"}, name


def test_the_reports_per_trial_table_shows_the_brace_off_match_of_trials_csv(
    small_report: str, tables: Path
) -> None:
    """Each configuration's section lists, per trial, the brace-off scaling error, runs and clipped
    fraction that trials.csv carries (one reader), and flags a trial the scaling left outside the
    tolerance."""
    rows = _rows(tables / "trials.csv")
    assert rows and all(r["brace_off_scaling_runs"] == "2" for r in rows)
    for r in rows:
        section = re.search(
            rf'<section class="config" id="config-{r["configuration"]}">.*?</section>', small_report, re.S
        )
        assert section is not None
        table = re.search(r'<table class="trial-match">.*?</table>', section.group(0), re.S)
        assert table is not None
        row = re.search(rf"<tr><td>{r['trial']}</td>.*?</tr>", table.group(0), re.S)
        assert row is not None
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row.group(0), re.S)
        error, runs, clipped = cells[1:]
        assert error.startswith(f"{float(r['brace_off_scaling_error_deg']):.3f}")
        assert runs == "2"
        assert clipped == f"{float(r['clipped_fraction']):.3f}"
        outside = r["brace_off_scaling_converged"] == "False"
        assert outside == (r["trial"] == "2")  # the builder's trial 2 stayed outside the tolerance
        assert ("outside the tolerance" in error) == outside
        assert float(r["brace_off_scaling_error_deg"]) == pytest.approx(
            0.25 if outside else 0.02 * int(r["trial"])
        )


def test_cli_export_only_writes_the_rows_of_those_configurations(small_archive: Path, tmp_path: Path) -> None:
    keys = [cfg.key for cfg in load_report_data(small_archive, workers=1).configurations]
    assert len(keys) > 1
    assert main(["--export", str(small_archive), "--output", str(tmp_path), "--only", str(keys[-1])]) == 0
    for name in ("cycles.csv", "trials.csv", "configurations.csv"):
        rows = _rows(tmp_path / name)
        assert rows and {int(r["configuration"]) for r in rows} == {keys[-1]}, name


def test_cli_export_only_a_key_the_archive_lacks_exits_2_naming_it(
    small_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--export", str(small_archive), "--output", str(tmp_path / "out"), "--only", "999"]) == 2
    assert "999" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_predictions_csv_gives_each_models_angles_and_marks_an_extrapolation(
    small_archive: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The declared columns first, in their order, then each model's angles: those fitted on (A's) and
    those predicted (B's), how far B's reach beyond A's, and whether that is an extrapolation."""
    from protocol_runner.report import tidy
    from protocol_runner.report.predictions import AngleRanges, ElementPrediction, Prediction

    empty = np.zeros(0)
    element = ElementPrediction(
        0.5, 16.7, 15.7, 17.4, 16.1, empty, empty, empty, AngleRanges((41.0, 84.0), (1.0, 109.0))
    )
    wide = Prediction(
        12, 14, "", 91.8, 1.0, "", element, bouc_wen_ranges=AngleRanges((-21.0, 22.0), (-58.0, 50.0))
    )
    monkeypatch.setattr(tidy, "predictions", lambda archive, text, figures: (wide,))
    export_tables(small_archive, tmp_path)
    with (tmp_path / "predictions.csv").open(encoding="utf-8", newline="") as fh:
        header = next(csv.reader(fh))
    assert header == [
        "from_configuration",
        "to_configuration",
        "joint",
        "model",
        "rmse_nm",
        "energy_predicted_j",
        "energy_predicted_ci95_low_j",
        "energy_predicted_ci95_high_j",
        "energy_measured_j",
        "source_range_low_deg",
        "source_range_high_deg",
        "target_range_low_deg",
        "target_range_high_deg",
        "beyond_source_deg",
        "extrapolated",
    ]
    elements, bouc_wen = _rows(tmp_path / "predictions.csv")
    assert (elements["model"], elements["rmse_nm"], elements["energy_predicted_j"]) == (
        "elements",
        "0.5",
        "16.7",
    )
    ranges = (
        "source_range_low_deg",
        "source_range_high_deg",
        "target_range_low_deg",
        "target_range_high_deg",
    )
    assert [elements[c] for c in ranges] == ["41.0", "84.0", "1.0", "109.0"]
    assert (elements["beyond_source_deg"], elements["extrapolated"]) == ("40.0", "True")
    assert (bouc_wen["model"], bouc_wen["rmse_nm"], bouc_wen["energy_predicted_j"]) == (
        "bouc_wen",
        "91.8",
        "",
    )
    assert [bouc_wen[c] for c in ranges] == ["-21.0", "22.0", "-58.0", "50.0"]
    assert (bouc_wen["beyond_source_deg"], bouc_wen["extrapolated"]) == ("37.0", "True")
