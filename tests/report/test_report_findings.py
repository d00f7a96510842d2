"""Chapter 5 findings checked against archives built to agree or to disagree with the thesis."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.report.findings import Finding, comparison_keys, evaluate_findings
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import ReportData
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, thesis_like_specs, write_archive


def _load(tmp_path: Path, configs: list[ConfigSpec], **kw: object) -> ReportData:
    spec = ArchiveSpec(configs=configs, duration_s=17.0, **kw)  # type: ignore[arg-type]
    return load_report_data(write_archive(tmp_path / "archive.h5", spec), workers=1)


def _by_title(findings: tuple[Finding, ...], fragment: str) -> Finding:
    matches = [f for f in findings if fragment in f.title]
    assert len(matches) == 1, fragment
    return matches[0]


def _spring_specs(energies: dict[int, float]) -> list[ConfigSpec]:
    # 17: K0, 20: K1, 14: K2, 23: K3 - stiffer springs: steeper slope, smaller reachable range (§5.4)
    slope = {17: 0.02, 20: 0.12, 14: 0.3, 23: 0.45}
    reach = {17: (2.0, 128.0), 20: (4.0, 120.0), 14: (5.0, 109.0), 23: (8.0, 98.0)}
    return [
        ConfigSpec(
            key=k,
            energy_j=e,
            n_trials=1,
            slope_nm_per_deg=slope[k],
            angle_range_deg=reach[k],
            energy_spread=0.0,
        )
        for k, e in energies.items()
    ]


@pytest.fixture(scope="module")
def thesis_findings(tmp_path_factory: pytest.TempPathFactory) -> tuple[Finding, ...]:
    configs = thesis_like_specs(n_trials=1)
    configs = [c for c in configs if c.key != 14] + _spring_specs({17: 5.0, 20: 6.5, 14: 6.0, 23: 5.5})
    for c in configs:
        if c.key in (8, 3, 9):  # preload steepens the slope (§5.5); position 1 is the greatest preload
            c.slope_nm_per_deg = {9: 0.25, 3: 0.3, 8: 0.35}[c.key]
    spec = ArchiveSpec(configs=configs, duration_s=17.0)
    data = load_report_data(write_archive(tmp_path_factory.mktemp("thesis") / "archive.h5", spec), workers=1)
    return evaluate_findings(data)


def test_every_finding_agrees_with_data_built_like_the_thesis(thesis_findings: tuple[Finding, ...]) -> None:
    disagreeing = [(f.title, f.numbers) for f in thesis_findings if f.agrees is not True]
    assert disagreeing == []
    assert len(thesis_findings) == 11


def test_findings_cite_thesis_sections_and_show_numbers(thesis_findings: tuple[Finding, ...]) -> None:
    for f in thesis_findings:
        assert f.section.startswith("5.")
        assert f.thesis_statement and "config" in f.numbers


def test_friction_finding_disagrees_when_energy_falls_with_friction(tmp_path: Path) -> None:
    data = _load(
        tmp_path, [ConfigSpec(key=k, energy_j=e) for k, e in {4: 4.0, 5: 3.0, 6: 2.0, 7: 1.0}.items()]
    )
    finding = _by_title(evaluate_findings(data), "friction")
    assert finding.agrees is False
    assert "config 4 (friction 0.00 N·m): 4.0" in finding.numbers


def test_findings_without_their_configurations_are_undecided(tmp_path: Path) -> None:
    data = _load(tmp_path, [ConfigSpec(key=4), ConfigSpec(key=5, energy_j=2.0)])
    findings = evaluate_findings(data)
    assert _by_title(findings, "friction").agrees is True
    for fragment in (
        "range of motion",
        "Half speed",
        "preload loses",
        "No clear relation",
        "110°",
        "25-105°",
    ):
        f = _by_title(findings, fragment)
        assert f.agrees is None and f.numbers.startswith("Not enough data")


def test_half_speed_losing_less_than_full_speed_disagrees(tmp_path: Path) -> None:
    data = _load(
        tmp_path,
        [
            ConfigSpec(key=10, energy_j=6.0, energy_spread=0.0),
            ConfigSpec(key=11, energy_j=4.0, energy_spread=0.0),
        ],
    )
    assert _by_title(evaluate_findings(data), "Half speed").agrees is False


def test_a_clear_monotonic_spring_relation_contradicts_the_thesis(tmp_path: Path) -> None:
    data = _load(tmp_path, _spring_specs({17: 2.0, 20: 4.0, 14: 6.0, 23: 8.0}))
    findings = evaluate_findings(data)
    assert _by_title(findings, "No clear relation").agrees is False
    assert _by_title(findings, "steepen the torque-angle slope").agrees is True
    assert _by_title(findings, "shrink the reachable range").agrees is True


def test_springs_that_flatten_the_slope_disagree(tmp_path: Path) -> None:
    specs = _spring_specs({17: 5.0, 20: 6.5, 14: 6.0, 23: 5.5})
    for spec, slope in zip(specs, (0.45, 0.3, 0.12, 0.02), strict=True):
        spec.slope_nm_per_deg = slope
    assert (
        _by_title(evaluate_findings(_load(tmp_path, specs)), "steepen the torque-angle slope").agrees is False
    )


def test_k2_passing_well_beyond_110_degrees_disagrees(tmp_path: Path) -> None:
    data = _load(tmp_path, [ConfigSpec(key=3, angle_range_deg=(2.0, 129.0))])
    finding = _by_title(evaluate_findings(data), "110°")
    assert finding.agrees is False and "129.0°" in finding.numbers


def test_r1_stop_holding_the_robot_at_its_stops_disagrees(tmp_path: Path) -> None:
    data = _load(tmp_path, [ConfigSpec(key=1, angle_range_deg=(40.0, 90.0))])
    assert _by_title(evaluate_findings(data), "25-105°").agrees is False


def test_comparison_keys_come_from_the_archive_when_present(tmp_path: Path) -> None:
    configs = [ConfigSpec(key=k, energy_j=e) for k, e in {4: 9.0, 5: 2.0, 6: 3.0, 7: 4.0}.items()]
    path = write_archive(tmp_path / "archive.h5", ArchiveSpec(configs=configs, duration_s=17.0))
    with h5py.File(path, "a") as f:  # the protocol compares only 5-7 for friction
        f["comparisons/friction"].attrs["configurations"] = np.asarray([5, 6, 7])
    data = load_report_data(path, workers=1)
    assert comparison_keys(data, "friction") == (5, 6, 7)
    assert _by_title(evaluate_findings(data), "friction").agrees is True


def test_thesis_keys_are_the_fallback_without_comparisons(tmp_path: Path) -> None:
    data = _load(tmp_path, [ConfigSpec(key=4)], comparisons=False)
    assert comparison_keys(data, "friction") == (4, 5, 6, 7)
    assert comparison_keys(data, "stiffness") == (17, 20, 14, 23)
    assert comparison_keys(data, "preload") == (8, 3, 9)


def test_the_closest_archive_comparison_wins_when_several_share_a_parameter(tmp_path: Path) -> None:
    # knee_phase1.yaml lists brace_rom [1, 2, 3] and energy_restraint (also brace_rom) [1, 2, 3, 12, 13, 14]
    restraint = ("brace_rom", "5.2", "Restraint", (1, 2, 3, 12, 13, 14))  # listed first (same §, name)
    data = _load(tmp_path, [ConfigSpec(key=1)], extra_comparisons={"a_restraint": restraint})
    assert comparison_keys(data, "brace_rom") == (1, 2, 3)
