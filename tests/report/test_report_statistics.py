"""Statistics across configurations inside one report: differences of energy per cycle with Welch
intervals for each declared comparison (its declared pairs, else adjacent configurations), Holm-adjusted
within the comparison, and the repeatability of a DECLARED group of identical configurations
(`report.repeatability`), both on trial means, checked against scipy.stats."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.report.differences import declared_differences, declared_repeatability
from protocol_runner.report.evaluate import format_p
from protocol_runner.report.headline import trial_values
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import ReportData
from protocol_runner.report.render import generate_report
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

KNEE_YAML = Path(__file__).resolve().parents[2] / "protocols" / "knee_phase1.yaml"

REPEAT_TEXT = """name: knee_synthetic
report:
  repeatability:
    - {name: baseline, text: "one configuration in four sets", configurations: [3, 6, 10, 14]}
"""


def _data(tmp_path: Path, configs: list[ConfigSpec], text: str, name: str = "a") -> ReportData:
    (tmp_path / name).mkdir()
    spec = ArchiveSpec(configs=configs, duration_s=17.0, protocol_text=text)
    return load_report_data(write_archive(tmp_path / name / "archive.h5", spec), workers=1)


@pytest.fixture(scope="module")
def repeat_data(tmp_path_factory: pytest.TempPathFactory) -> ReportData:
    # the same configuration in four sets, each set a little off the others (mounting), 3 trials each
    energies = {3: 6.0, 6: 6.3, 10: 5.8, 14: 6.1}
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=3, energy_spread=0.03) for k, e in energies.items()]
    return _data(tmp_path_factory.mktemp("repeat"), configs, REPEAT_TEXT)


def test_adjacent_differences_are_welch_intervals_on_trial_means(small_archive: Path) -> None:
    data = load_report_data(small_archive, workers=1)
    friction = next(c for c in data.comparisons if c.name == "friction")
    diffs = declared_differences(data, friction)
    assert [(d.base, d.key) for d in diffs] == [(4, 5), (5, 6), (6, 7)]
    for d in diffs:
        a = trial_values(data.configuration(d.base), "energy_per_cycle")  # type: ignore[arg-type]
        b = trial_values(data.configuration(d.key), "energy_per_cycle")  # type: ignore[arg-type]
        ref = stats.ttest_ind(b, a, equal_var=False)
        ci = ref.confidence_interval(0.95)
        assert d.energy.difference == pytest.approx(np.mean(b) - np.mean(a), rel=1e-12)
        assert (d.energy.low, d.energy.high) == (
            pytest.approx(ci.low, rel=1e-9),
            pytest.approx(ci.high, rel=1e-9),
        )
        assert d.energy.p_value == pytest.approx(ref.pvalue, rel=1e-9)
        assert d.trials == (len(a), len(b)) == (2, 2)
        assert d.energy.difference > 0  # 1.5, 2.5, 4.0, 6.0 J per cycle: every step loses more
        assert d.label == f"{d.key} minus {d.base}"
    raw = sorted(d.energy.p_value for d in diffs)  # Holm over the table's three differences
    expected = [3 * raw[0], max(3 * raw[0], 2 * raw[1]), max(3 * raw[0], 2 * raw[1], raw[2])]
    assert sorted(d.p_adjusted for d in diffs) == [pytest.approx(min(1.0, e)) for e in expected]


def test_the_report_prints_one_differences_table_per_comparison(
    small_archive: Path, small_report: str
) -> None:
    table = re.search(
        r'<table class="differences" id="differences-friction">(.*?)</table>', small_report, re.S
    )
    assert table is not None
    rows = re.findall(
        r'data-from="(\d+)" data-to="(\d+)" data-significant="(yes|no)">(.*?)</tr>', table[1], re.S
    )
    assert [(f, t) for f, t, _, _ in rows] == [("4", "5"), ("5", "6"), ("6", "7")]
    data = load_report_data(small_archive, workers=1)
    friction = next(c for c in data.comparisons if c.name == "friction")
    for (_, _, flag, body), d in zip(rows, declared_differences(data, friction), strict=True):
        assert f"[{d.energy.low:.2f}, {d.energy.high:.2f}]" in body
        assert f"<td>{d.key} minus {d.base}</td>" in body
        assert f'<td class="num">{format_p(d.p_adjusted)}</td>' in body  # the Holm-adjusted p beside p
        assert flag == ("yes" if d.p_adjusted <= 0.05 else "no")
    assert "The family is the differences of one table" in small_report


def test_a_declared_group_gets_between_set_cv_and_icc_against_one_way_anova(repeat_data: ReportData) -> None:
    groups, problems = declared_repeatability(repeat_data)
    assert problems == ()
    (group,) = groups
    assert group.spec.name == "baseline" and group.present == (3, 6, 10, 14) and group.missing == ()
    units = [trial_values(repeat_data.configuration(k), "energy_per_cycle") for k in (3, 6, 10, 14)]  # type: ignore[arg-type]
    f = stats.f_oneway(*units).statistic
    assert group.result.icc == pytest.approx((f - 1) / (f + 3 - 1), rel=1e-9)  # balanced: k = 3 trials
    means = [np.mean(u) for u in units]
    assert group.result.between_cv == pytest.approx(np.std(means, ddof=1) / np.mean(means), rel=1e-12)
    assert (group.result.groups, group.result.units) == (4, 12)


def test_the_summary_shows_the_declared_group(repeat_data: ReportData, tmp_path: Path) -> None:
    html = generate_report(Path(repeat_data.session.archive_path), tmp_path / "r.html", workers=1).read_text(
        encoding="utf-8"
    )
    item = re.search(r'<li data-repeatability="baseline">(.*?)</li>', html, re.S)
    assert item is not None
    (group,) = declared_repeatability(repeat_data)[0]
    assert "configurations 3, 6, 10, 14" in item[1]
    assert f"between-set CV {group.result.between_cv * 100:.1f} %" in item[1]
    assert group.result.icc > 0
    assert f"ICC {group.result.icc:.2f} (12 trials in 4 configurations)" in item[1]
    assert html.index('id="repeatability"') < html.index('id="configurations"')


def test_identical_configurations_that_are_not_declared_get_no_repeatability(tmp_path: Path) -> None:
    # auto-detection is gone: only a declared group is reported
    configs = [ConfigSpec(key=k, energy_j=6.0, n_trials=3) for k in (3, 6, 10, 14)]
    data = _data(tmp_path, configs, "name: knee_synthetic\n")
    assert declared_repeatability(data) == ((), ())
    html = generate_report(Path(data.session.archive_path), tmp_path / "r.html", workers=1).read_text(
        encoding="utf-8"
    )
    assert 'id="repeatability"' not in html


def test_a_group_partly_absent_from_the_archive_says_which(tmp_path: Path) -> None:
    configs = [ConfigSpec(key=k, energy_j=6.0, n_trials=3) for k in (3, 6)]
    (group,), _ = declared_repeatability(_data(tmp_path, configs, REPEAT_TEXT))
    assert group.present == (3, 6) and group.missing == (10, 14)
    assert group.result.groups == 2


def test_an_unreadable_group_in_an_old_archive_is_reported_not_raised(tmp_path: Path) -> None:
    text = "name: x\nreport:\n  repeatability:\n    - {name: g, configurations: [3]}\n"
    groups, problems = declared_repeatability(_data(tmp_path, [ConfigSpec(key=3)], text))
    assert groups == ()
    assert len(problems) == 1 and problems[0].startswith("report.repeatability[0].configurations")


def _knee_with(tmp_path: Path, groups: list[dict[str, object]]) -> str:
    folder = tmp_path / "p"
    shutil.copytree(KNEE_YAML.parent, folder)
    text = KNEE_YAML.read_text(encoding="utf-8")
    assert yaml.safe_load(text)["report"]["repeatability"][0]["configurations"] == [3, 6, 10, 14]
    start = text.index("  repeatability:")
    end = text.index("  comparisons:", start)
    block = "  repeatability:\n" + "".join(
        f"    - {yaml.safe_dump(g, default_flow_style=True).strip()}\n" for g in groups
    )
    (folder / "knee_phase1.yaml").write_text(text[:start] + block + text[end:], encoding="utf-8")
    with pytest.raises(InvalidInput) as info:
        load_protocol(folder / "knee_phase1.yaml", display_name="knee_phase1.yaml")
    return info.value.message


@pytest.mark.parametrize(
    ("groups", "needles"),
    [
        (
            [{"name": "g", "configurations": [3, 6, 7]}],
            ["configuration 7 does not have the settings of configuration 3", "friction 3 vs 2"],
        ),
        ([{"name": "g", "configurations": [3, 99]}], ["no configuration has key 99"]),
        ([{"name": "g", "configurations": [3, 3]}], ["configuration 3 is listed twice"]),
        (
            [{"name": "g", "configurations": [3, 6]}, {"name": "g", "configurations": [10, 14]}],
            ["repeatability group name 'g' is used twice"],
        ),
        ([{"name": "g", "configurations": [3]}], ["at least 2"]),
    ],
)
def test_a_bad_repeatability_group_is_refused_with_file_line_and_field(
    tmp_path: Path, groups: list[dict[str, object]], needles: list[str]
) -> None:
    message = _knee_with(tmp_path, groups)
    assert all(n in message for n in needles), message
    assert "repeatability" in message
    assert re.search(r"knee_phase1\.yaml.*line \d+", message) or re.search(r"knee_phase1\.yaml:\d+", message)


PAIRED_TEXT = """name: knee_synthetic
report:
  comparisons:
    - {name: restraint, parameter: brace_rom, title: "Restrained against smaller trajectory",
       configurations: [1, 2, 3, 12, 13, 14], pairs: [[12, 1], [13, 2], [14, 3]]}
"""


def test_declared_pairs_are_shown_in_their_order_as_b_minus_a(tmp_path: Path) -> None:
    """A paired design (1 against 12, 2 against 13, 3 against 14) gives those three differences, in the
    declared order and named "1 minus 12", never the adjacent "12 minus 3"."""
    energies = {1: 6.0, 2: 5.0, 3: 4.0, 12: 3.0, 13: 4.5, 14: 4.0}
    configs = [ConfigSpec(key=k, energy_j=e, n_trials=3) for k, e in energies.items()]
    spec = ArchiveSpec(
        configs=configs,
        duration_s=17.0,
        protocol_text=PAIRED_TEXT,
        extra_comparisons={"restraint": ("brace_rom", "", "Restrained", (1, 2, 3, 12, 13, 14))},
    )
    data = load_report_data(write_archive(tmp_path / "archive.h5", spec), workers=1)
    comparison = next(c for c in data.comparisons if c.name == "restraint")
    diffs = declared_differences(data, comparison)
    assert [d.label for d in diffs] == ["1 minus 12", "2 minus 13", "3 minus 14"]
    assert [d.energy.difference for d in diffs] == [
        pytest.approx(3.0, abs=0.1),
        pytest.approx(0.5, abs=0.1),
        pytest.approx(0.0, abs=0.1),
    ]
    html = generate_report(Path(data.session.archive_path), tmp_path / "r.html", workers=1).read_text(
        encoding="utf-8"
    )
    table = re.search(r'<table class="differences" id="differences-restraint">(.*?)</table>', html, re.S)
    assert table is not None
    assert re.findall(r"<td>(\d+ minus \d+)</td>", table[1]) == ["1 minus 12", "2 minus 13", "3 minus 14"]


def test_pairs_must_come_from_the_comparison() -> None:
    from protocol_runner.protocol.schema import ComparisonSpec

    base = {"name": "c", "parameter": "p", "title": "t", "configurations": [1, 2]}
    assert ComparisonSpec.model_validate({**base, "pairs": [[2, 1]]}).pairs == [(2, 1)]
    with pytest.raises(ValueError, match="configuration 3 is not in this comparison"):
        ComparisonSpec.model_validate({**base, "pairs": [[1, 3]]})
    with pytest.raises(ValueError, match="with itself"):
        ComparisonSpec.model_validate({**base, "pairs": [[1, 1]]})


def test_a_negative_icc_is_shown_as_zero_with_a_note(tmp_path: Path) -> None:
    """Four sets with identical means and trial scatter: ICC(1) estimates below 0 (the sets differ less
    than their trials); the summary shows ICC 0.00 and says why, never a bare negative correlation."""
    configs = [ConfigSpec(key=k, energy_j=6.0, n_trials=3, energy_spread=0.05) for k in (3, 6, 10, 14)]
    data = _data(tmp_path, configs, REPEAT_TEXT)
    (group,) = declared_repeatability(data)[0]
    assert group.result.icc < 0 and group.result.icc_shown == 0.0
    html = generate_report(Path(data.session.archive_path), tmp_path / "r.html", workers=1).read_text(
        encoding="utf-8"
    )
    item = re.search(r'<li data-repeatability="baseline">(.*?)</li>', html, re.S)
    assert item is not None
    assert f"ICC 0.00 (negative estimate ({group.result.icc:.2f}) shown as 0:" in item[1]
    assert f"ICC {group.result.icc:.2f}" not in item[1]
