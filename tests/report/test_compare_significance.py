"""`--compare` decides each quantity on its own: energy per cycle and range reached, B minus
A on trial means with Welch intervals, each verdict at p < 0.025 (Bonferroni over the two quantities), and
the page names the quantity each verdict is about."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from scipy import stats

from protocol_runner.report.compare import ALPHA_EACH, compare_archives, render_comparison
from protocol_runner.report.headline import trial_values
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

BASE = {4: (1.5, (5.0, 109.0)), 5: (2.5, (5.0, 109.0)), 6: (4.0, (5.0, 109.0)), 7: (6.0, (5.0, 109.0))}


def _archive(folder: Path, seed: int, changes: dict[int, tuple[float, tuple[float, float]]]) -> Path:
    folder.mkdir()
    configs = [
        ConfigSpec(key=k, energy_j=e, n_trials=4, angle_range_deg=r, energy_spread=0.02)
        for k, (e, r) in (BASE | changes).items()
    ]
    return write_archive(folder / "archive.h5", ArchiveSpec(configs=configs, duration_s=17.0, seed=seed))


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("cmp")
    a = _archive(root / "a", seed=1, changes={})
    # B: configuration 5 reaches a narrower range (same energy), configuration 6 loses 50 % more energy
    b = _archive(root / "b", seed=2, changes={5: (2.5, (15.0, 100.0)), 6: (6.0, (5.0, 109.0))})
    return a, b


def test_each_quantity_has_its_own_verdict_and_the_pair_says_which(pair: tuple[Path, Path]) -> None:
    result = compare_archives(*pair)
    by_key = {p.a.key: p for p in result.pairs}
    assert {k: p.verdict for k, p in by_key.items()} == {
        4: "none",
        5: "range reached",
        6: "energy per cycle",
        7: "none",
    }
    assert [k for k, p in by_key.items() if p.significant] == [5, 6]
    assert result.n_significant == 2
    assert by_key[5].range.difference == pytest.approx(-(109 - 5) + (100 - 15), abs=2.0)


def test_verdicts_use_welchs_p_value_at_the_bonferroni_level(pair: tuple[Path, Path]) -> None:
    assert ALPHA_EACH == 0.025
    for p in compare_archives(*pair).pairs:
        for metric, w, flag in (
            ("energy_per_cycle", p.energy, p.energy_differs),
            ("range_reached", p.range, p.range_differs),
        ):
            a, b = trial_values(p.a, metric), trial_values(p.b, metric)
            if min(len(set(a)), len(set(b))) > 1:  # scipy needs spread in each group
                ref = stats.ttest_ind(b, a, equal_var=False)
                assert w.p_value == pytest.approx(ref.pvalue, rel=1e-9)
            assert flag == (w.p_value < 0.025)


def test_the_page_and_the_printed_table_name_the_quantity_of_each_verdict(
    pair: tuple[Path, Path], tmp_path: Path
) -> None:
    result = compare_archives(*pair)
    html = render_comparison(result, tmp_path / "c.html").read_text(encoding="utf-8")
    rows = re.findall(
        r'data-a="(\d+)" data-b="\d+" data-significant="(yes|no)"\s+data-energy="(yes|no)" data-range="(yes|no)"',
        html,
    )
    assert rows == [
        ("4", "no", "no", "no"),
        ("5", "yes", "no", "yes"),
        ("6", "yes", "yes", "no"),
        ("7", "no", "no", "no"),
    ]
    assert (
        "<th>Energy differs</th>" in html
        and "<th>Range differs</th>" in html
        and "<th>Differs in</th>" in html
    )
    assert "p &lt; 0.025 (Bonferroni over the two quantities" in html
    table = result.table().splitlines()
    assert table[0].endswith("differs in")
    assert table[2].endswith("range reached") and table[3].endswith("energy per cycle")
    assert "2 differ in energy per cycle or range reached (each at p < 0.025)" in table[-1]
