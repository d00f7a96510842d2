"""Expectations declared in a protocol's YAML, decided by the one generic evaluator: the knee's Chapter 5
statements on data built like the thesis, the verdict table with Holm-adjusted p-values, the archive's
record, and the declarations the schema refuses."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from markupsafe import escape
from pydantic import ValidationError

from protocol_runner.protocol.expectations import ExpectationSpec, check_expectations
from protocol_runner.report.declared import declared_entries
from protocol_runner.report.evaluate import (
    TUNED_LABEL,
    Verdict,
    evaluate_all,
    evaluate_expectations,
    format_p,
)
from protocol_runner.report.headline import trial_values
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import ReportData
from protocol_runner.report.render import generate_report
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, thesis_like_specs, write_archive


def evaluate_expectation(spec: ExpectationSpec, data: ReportData) -> Verdict:
    """`spec` decided on `data` alone (a single-joint archive: a family of one)."""
    return evaluate_all([spec], data)[0]


KNEE_YAML = Path(__file__).resolve().parents[2] / "protocols" / "knee_phase1.yaml"


def _knee_text(edit: dict[str, dict[str, object]] | None = None) -> str:
    """knee_phase1.yaml as text, with some expectations' fields replaced (by id)."""
    doc = yaml.safe_load(KNEE_YAML.read_text(encoding="utf-8"))
    for entry in doc["expectations"]:
        entry.update((edit or {}).get(entry["id"], {}))
    return yaml.safe_dump(doc, sort_keys=False)


def _thesis_configs() -> list[ConfigSpec]:
    configs = thesis_like_specs(n_trials=3)
    slopes = {9: 0.25, 3: 0.3, 8: 0.35}  # preload steepens the slope (§5.5); position 1 = most preload
    for c in configs:
        c.slope_nm_per_deg = slopes.get(c.key, c.slope_nm_per_deg)
        if c.key in (4, 5, 6, 7):  # more friction, less range (§5.3)
            c.angle_range_deg = {4: (5.0, 112.0), 5: (6.0, 110.0), 6: (7.0, 108.0), 7: (8.0, 104.0)}[c.key]
        if c.key == 10:  # full speed reaches less than half speed (§5.1)
            c.angle_range_deg = (8.0, 109.0)
    return configs


def _archive(tmp_path: Path, configs: list[ConfigSpec], text: str, **kw: object) -> Path:
    spec = ArchiveSpec(configs=configs, duration_s=17.0, protocol_text=text, **kw)  # type: ignore[arg-type]
    return write_archive(tmp_path / "archive.h5", spec)


def _verdicts(data: ReportData) -> dict[str, str]:
    return {v.spec.id: v.verdict for v in evaluate_expectations(data).verdicts}


@pytest.fixture(scope="module")
def thesis_data(tmp_path_factory: pytest.TempPathFactory) -> ReportData:
    path = _archive(tmp_path_factory.mktemp("thesis"), _thesis_configs(), _knee_text())
    return load_report_data(path, workers=1)


def test_knee_expectations_come_from_the_archived_yaml(thesis_data: ReportData) -> None:
    specs, problems = declared_entries(thesis_data.protocol_text, ("expectations",), ExpectationSpec)
    assert problems == ()
    ids = {s.id for s in specs}
    # every Chapter 5 statement, including those the old code never checked
    assert {"friction_range", "speed_range", "k2_upper_limit", "stop_slack_low", "stop_slack_high"} <= ids
    assert len(ids) == len(specs) >= 14


def test_data_built_like_the_thesis_meets_the_evaluable_expectations(thesis_data: ReportData) -> None:
    verdicts = _verdicts(thesis_data)
    met = {
        "speed_energy",
        "speed_range",
        "k2_upper_limit",
        "stop_slack_low",
        "stop_slack_high",
        "friction_range",
        "preload_slope",
        "energy_friction",
        "energy_rom",
        "energy_preload",
    }
    assert {k: verdicts[k] for k in met} == dict.fromkeys(met, "met")
    # the synthetic archive has no spring configurations 20 and 23: not evaluable, with the reason
    assert verdicts["stiffness_slope"] == "not evaluable"
    reason = next(
        v.reason for v in evaluate_expectations(thesis_data).verdicts if v.spec.id == "stiffness_slope"
    )
    assert "configurations 20, 23 were not run (the session ran only 1-14)" in reason


def test_changing_a_threshold_in_the_yaml_changes_the_verdict(tmp_path: Path) -> None:
    configs = [c for c in _thesis_configs() if c.key in (2, 3)]
    (tmp_path / "a").mkdir()
    before = load_report_data(_archive(tmp_path / "a", configs, _knee_text()), workers=1)
    assert _verdicts(before)["k2_upper_limit"] == "met"
    (tmp_path / "b").mkdir()
    edited = _knee_text({"k2_upper_limit": {"interval": [80, 100]}})
    after = load_report_data(_archive(tmp_path / "b", configs, edited), workers=1)
    assert _verdicts(after)["k2_upper_limit"] == "not met"
    reason = next(v.reason for v in evaluate_expectations(after).verdicts if v.spec.id == "k2_upper_limit")
    assert "must lie inside [80, 100] deg" in reason and "(fails)" in reason


def test_reversed_trend_is_not_met_and_the_numbers_are_shown(tmp_path: Path) -> None:
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=3) for k, e in {4: 8.0, 5: 6.0, 6: 4.0, 7: 3.0}.items()]
    data = load_report_data(_archive(tmp_path, configs, _knee_text()), workers=1)
    verdict = next(v for v in evaluate_expectations(data).verdicts if v.spec.id == "energy_friction")
    assert verdict.verdict == "not met"
    assert "8.02 > 5.96 > 4.01 > 3.01 J" in verdict.reason  # the signs the data show
    assert verdict.reason.count("(fails)") == 3  # every step goes the other way
    assert [e.key for e in verdict.evidence] == [4, 5, 6, 7]
    assert verdict.evidence[0].mean == pytest.approx(8.0, rel=0.05)


def test_one_trial_is_not_evaluable(tmp_path: Path) -> None:
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=1) for k, e in {10: 6.0, 11: 7.0}.items()]
    data = load_report_data(_archive(tmp_path, configs, _knee_text()), workers=1)
    verdict = next(v for v in evaluate_expectations(data).verdicts if v.spec.id == "speed_energy")
    assert verdict.verdict == "not evaluable"
    assert "configuration 11 has 1 trial with energy per cycle" in verdict.reason


@pytest.mark.parametrize(
    ("relation", "fields", "expected"),
    [
        ("greater", {"value": 5.0}, "met"),
        ("greater", {"value": 7.0}, "not met"),
        ("less", {"value": 7.0}, "met"),
        ("equal", {"value": 6.2, "margin": 0.5}, "met"),
        ("equal", {"value": 6.2, "margin": 0.05}, "not met"),
        ("inside", {"interval": [5.0, 7.0]}, "met"),
        ("inside", {"interval": [6.5, 7.0]}, "not met"),
    ],
)
def test_relations_against_a_value(
    tmp_path: Path, relation: str, fields: dict[str, object], expected: str
) -> None:
    data = load_report_data(
        _archive(tmp_path, [ConfigSpec(key=3, energy_j=6.0, n_trials=4)], "{}"), workers=1
    )
    spec = ExpectationSpec.model_validate(
        {
            "id": "x",
            "text": "t",
            "metric": "energy_per_cycle",
            "configurations": [3],
            "relation": relation,
            **fields,
        }
    )
    assert evaluate_expectation(spec, data).verdict == expected


def test_no_trend_is_met_by_a_zigzag_and_not_by_a_clear_rise(tmp_path: Path) -> None:
    zig = [ConfigSpec(key=k, energy_j=e, n_trials=3) for k, e in {20: 5.0, 14: 6.5, 23: 5.5}.items()]
    data = load_report_data(_archive(tmp_path, zig, _knee_text()), workers=1)
    assert _verdicts(data)["energy_springs"] == "met"
    (tmp_path / "rise").mkdir()
    rise = [ConfigSpec(key=k, energy_j=e, n_trials=3) for k, e in {20: 5.0, 14: 6.5, 23: 8.0}.items()]
    data = load_report_data(_archive(tmp_path / "rise", rise, _knee_text()), workers=1)
    assert _verdicts(data)["energy_springs"] == "not met"


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"relation": "greater"}, "exactly one of `than`"),
        ({"relation": "equal", "value": 1.0}, "needs `margin`"),
        ({"relation": "no_trend"}, "needs `margin`"),
        ({"relation": "greater", "value": 1.0, "margin": 1.0}, "takes no `margin`"),
        ({"relation": "inside"}, "needs `interval"),
        ({"relation": "increasing", "configurations": [1]}, "two or more configurations"),
        ({"relation": "inside", "interval": [5, 1]}, "low < high"),
        ({"relation": "inside", "interval": [1, 5], "metric": "angle_percentile"}, "needs `percentile`"),
        ({"relation": "inside", "interval": [1, 5], "metric": "energy"}, "metric"),
    ],
)
def test_invalid_declarations_are_refused(fields: dict[str, object], message: str) -> None:
    entry = {"id": "x", "text": "t", "metric": "energy_per_cycle", "configurations": [1, 2], **fields}
    with pytest.raises(ValidationError) as info:
        ExpectationSpec.model_validate(entry)
    assert message in str(info.value)


def test_unknown_keys_and_duplicate_ids_are_located() -> None:
    spec = ExpectationSpec.model_validate(
        {"id": "a", "text": "t", "metric": "peak_torque", "configurations": [1, 99], "relation": "increasing"}
    )
    problems = list(check_expectations([spec, spec], {1, 2}))
    assert (("expectations", 0, "configurations", 1), "no configuration has key 99 (keys: 1-2)") in problems
    assert (("expectations", 1, "id"), "expectation id 'a' is used twice") in problems


def test_report_rows_carry_ids_verdicts_and_the_dry_run_honesty_label(
    tmp_path: Path, thesis_data: ReportData
) -> None:
    out = generate_report(Path(thesis_data.session.archive_path), tmp_path / "report.html", workers=1)
    html = out.read_text(encoding="utf-8")
    rows = re.findall(
        r'<tr class="expectation"[^>]*data-expectation="([^"]+)" data-verdict="([^"]+)">(.*?)</tr>',
        html,
        re.S,
    )
    by_id = {i: (v, body) for i, v, body in rows}
    assert by_id["energy_friction"][0] == "met"
    assert by_id["stiffness_slope"][0] == "not-evaluable"
    assert TUNED_LABEL in by_id["k2_upper_limit"][1]
    assert TUNED_LABEL not in by_id["energy_friction"][1]
    # the servo lag chosen for the simulator is named beside the verdict it decides
    assert f"{TUNED_LABEL} (lag_time_constant_s)" in by_id["speed_range"][1]
    # p and the Holm-adjusted p beside each verdict; the family is the evaluable expectations
    verdicts = {v.spec.id: v for v in evaluate_expectations(thesis_data).verdicts}
    family = sum(v.verdict != "not evaluable" for v in verdicts.values())
    assert f"The family is this campaign's\n{family} evaluable expectations" in html
    friction = verdicts["energy_friction"]
    cells = re.findall(r'<td class="num">([^<]*)</td>', by_id["energy_friction"][1])
    assert cells == [escape(format_p(friction.p_value)), escape(format_p(friction.p_adjusted))]
    assert friction.family == family and friction.p_adjusted >= friction.p_value
    assert re.findall(r'<td class="num">([^<]*)</td>', by_id["stiffness_slope"][1]) == ["—", "—"]


def test_a_robot_session_carries_no_honesty_label(tmp_path: Path) -> None:
    configs = [c for c in _thesis_configs() if c.key in (2, 3)]
    path = _archive(tmp_path, configs, _knee_text(), mode="robot")
    html = generate_report(path, tmp_path / "report.html", workers=1).read_text(encoding="utf-8")
    assert 'data-expectation="k2_upper_limit" data-verdict="met"' in html
    assert TUNED_LABEL not in html


def test_verdicts_are_recorded_in_the_archive_with_checksummed_evidence(tmp_path: Path) -> None:
    import h5py

    from protocol_runner.archive.verify import verify_path
    from protocol_runner.report.evaluate import record_verdicts

    configs = [c for c in _thesis_configs() if c.key in (2, 3)]
    path = _archive(tmp_path, configs, _knee_text())
    assert record_verdicts(path) >= 14
    with h5py.File(path, "r") as h5:
        grp = h5["expectations/k2_upper_limit"]
        assert grp.attrs["verdict"] == "met"
        assert '"interval":[100.0,120.0]' in grp.attrs["declaration"]
        evidence = json.loads(grp["evidence"][()])
        assert [(e["key"], e["trials"], e["unit"]) for e in evidence] == [(2, 3, "deg"), (3, 3, "deg")]
        assert evidence[0]["ci95_low"] < evidence[0]["mean"] < evidence[0]["ci95_high"]
        missing = json.loads(h5["expectations/energy_rom/evidence"][()])
        assert missing[0]["trials"] == 0 and missing[0]["mean"] is None
        assert h5["expectations/energy_rom"].attrs["verdict"] == "not evaluable"
    assert record_verdicts(path) >= 14  # rewriting replaces the group
    verdict = verify_path(path)
    assert not verdict.problems, verdict.lines


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        (
            "    configurations: [4, 5, 6, 7]\n  - id: energy_friction_per_degree",
            "    configurations: [4, 5, 6, 77]\n  - id: energy_friction_per_degree",
            "no configuration has key 77",
        ),
        (
            "    relation: inside\n    interval: [100, 120]",
            "    relation: inside\n    interval: [120, 100]",
            "low < high",
        ),
        (
            "    metric: range_reached\n    relation: less",
            "    metric: range_width\n    relation: less",
            "metric",
        ),
    ],
)
def test_a_bad_expectation_is_refused_with_file_line_and_field(
    tmp_path: Path, old: str, new: str, needle: str
) -> None:
    from protocol_runner.errors import InvalidInput
    from protocol_runner.protocol.loader import load_protocol

    folder = tmp_path / "p"
    shutil.copytree(KNEE_YAML.parent, folder)
    text = KNEE_YAML.read_text(encoding="utf-8")
    assert old in text
    (folder / "knee_phase1.yaml").write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(InvalidInput) as info:
        load_protocol(folder / "knee_phase1.yaml", display_name="knee_phase1.yaml")
    message = info.value.message
    assert needle in message and "expectations" in message
    assert re.search(r"knee_phase1\.yaml.*line \d+", message) or re.search(
        r"knee_phase1\.yaml:\d+", message
    ), message


_ADDED = {
    "id": "brake_added",
    "text": "the brake adds the same loss at both speeds",
    "metric": "energy_per_cycle",
    "relation": "equal",
    "configurations": [5],
    "baseline": [1],
    "than": [6],
    "than_baseline": [2],
    "margin": 0.7,
}


@pytest.mark.parametrize(("fast_brake_j", "expected"), [(7.35, "met"), (8.6, "not met")])
def test_a_difference_of_differences_decides_a_speed_independent_added_loss(
    tmp_path: Path, fast_brake_j: float, expected: str
) -> None:
    from scipy import stats

    energies = {1: 0.85, 5: 7.0, 2: 1.2, 6: fast_brake_j}  # slow: 1 (no brake), 5; fast: 2 (no brake), 6
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=3, energy_spread=0.005) for k, e in energies.items()]
    data = load_report_data(_archive(tmp_path, configs, "{}"), workers=1)
    verdict = evaluate_expectation(ExpectationSpec.model_validate(_ADDED), data)
    assert verdict.verdict == expected
    v = {k: np.asarray(trial_values(data.configuration(k), "energy_per_cycle")) for k in energies}  # type: ignore[arg-type]
    value = v[5].mean() - v[1].mean() - v[6].mean() + v[2].mean()
    var = [x.var(ddof=1) / x.size for x in v.values()]
    dof = sum(var) ** 2 / sum(s**2 / (x.size - 1) for s, x in zip(var, v.values(), strict=True))
    half = stats.t.ppf(0.95, dof) * np.sqrt(sum(var))  # the 90 % interval of the TOST at 0.05
    shown = re.search(
        r"^\(5 minus 1\) minus \(6 minus 2\): ([-\d.e]+) J, 90 % Welch-Satterthwaite interval "
        r"\[([-\d.e]+), ([-\d.e]+)\] J",
        verdict.reason,
    )
    assert shown is not None, verdict.reason
    assert float(shown[1]) == pytest.approx(value, rel=5e-3, abs=1e-3)
    assert float(shown[2]) == pytest.approx(value - half, rel=5e-3, abs=1e-3)
    assert float(shown[3]) == pytest.approx(value + half, rel=5e-3, abs=1e-3)
    assert [e.key for e in verdict.evidence] == [5, 1, 6, 2]


def test_what_a_setting_adds_over_its_baseline_compares_with_a_value(tmp_path: Path) -> None:
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=3) for k, e in {1: 1.0, 5: 7.0}.items()]
    data = load_report_data(_archive(tmp_path, configs, "{}"), workers=1)
    base = {"id": "x", "text": "t", "metric": "energy_per_cycle", "configurations": [5], "baseline": [1]}
    more = ExpectationSpec.model_validate({**base, "relation": "greater", "value": 5.0})
    less = ExpectationSpec.model_validate({**base, "relation": "greater", "value": 6.5})
    assert evaluate_expectation(more, data).verdict == "met"
    assert evaluate_expectation(less, data).verdict == "not met"  # adds 6 J, not more than 6.5
    reason = evaluate_expectation(more, data).reason
    assert reason.startswith("configuration 5 minus 1: 5.9") and "90 % Welch interval" in reason


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"relation": "increasing", "baseline": [1, 1]}, "takes no `baseline`"),
        ({"relation": "equal", "margin": 1, "value": 0, "baseline": [1]}, "as many configurations"),
        ({"relation": "greater", "value": 0, "than_baseline": [1, 1]}, "`than_baseline` needs `than`"),
        ({"relation": "greater", "than": [3, 4], "than_baseline": [1]}, "as many configurations as `than`"),
    ],
)
def test_invalid_baselines_are_refused(fields: dict[str, object], message: str) -> None:
    entry = {"id": "x", "text": "t", "metric": "energy_per_cycle", "configurations": [1, 2], **fields}
    with pytest.raises(ValidationError) as info:
        ExpectationSpec.model_validate(entry)
    assert message in str(info.value)


def test_unknown_baseline_keys_are_located() -> None:
    spec = ExpectationSpec.model_validate(_ADDED | {"baseline": [77], "than_baseline": [78]})
    problems = list(check_expectations([spec], {1, 2, 5, 6}))
    assert (("expectations", 0, "baseline", 0), "no configuration has key 77 (keys: 1-2, 5-6)") in problems
    assert (
        ("expectations", 0, "than_baseline", 0),
        "no configuration has key 78 (keys: 1-2, 5-6)",
    ) in problems


def test_expectations_are_decided_once_per_data_object(
    thesis_data: ReportData, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The session records the verdicts and then renders the report from the same data: decided once. A
    different data object (the same archive read again, or data changed with `replace`) is decided anew."""
    import dataclasses

    from protocol_runner.report import evaluate as findings

    calls: list[ReportData] = []
    real = findings.evaluate_all

    def counted(specs, data):  # type: ignore[no-untyped-def]
        calls.append(data)
        return real(specs, data)

    monkeypatch.setattr(findings, "evaluate_all", counted)
    first = evaluate_expectations(thesis_data)
    assert evaluate_expectations(thesis_data) is first
    assert len(calls) == 1
    assert {v.spec.id: v.verdict for v in first.verdicts}["k2_upper_limit"] == "met"
    edited = _knee_text({"k2_upper_limit": {"interval": [80, 100]}})
    changed = evaluate_expectations(dataclasses.replace(thesis_data, protocol_text=edited))
    assert len(calls) == 2
    assert {v.spec.id: v.verdict for v in changed.verdicts}["k2_upper_limit"] == "not met"  # decided anew
