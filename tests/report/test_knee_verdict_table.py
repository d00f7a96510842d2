"""End to end on a knee dry run: the campaign's expectations decided together, their verdict table with p
and the Holm-adjusted p beside each verdict, the family stated, the simulator-dependent verdicts labelled
with the values they depend on, and the same numbers recorded in the archive.

A copy of knee_phase1 with 3 sinusoid periods and no model fit, restricted to the speed pair (10, 11) and
two friction levels (4, 5): enough for the speed statements to be decided and for most others to be not
evaluable (their configurations were not run), which also leaves them out of the family.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import h5py
import pytest

from protocol_runner.analysis.statistics import holm
from protocol_runner.report.evaluate import TUNED_LABEL, evaluate_expectations, format_p
from protocol_runner.report.load import load_report_data

from ..short_knee import short_knee_session

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
ONLY = [4, 5, 10, 11]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def knee_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return short_knee_session(tmp_path_factory.mktemp("knee"), ONLY)


def test_the_verdict_table_shows_p_and_the_holm_adjusted_p(knee_session: Path) -> None:
    html = (knee_session / "report.html").read_text(encoding="utf-8")
    data = load_report_data(knee_session / "archive.h5", workers=1)
    verdicts = evaluate_expectations(data).verdicts
    evaluable = [v for v in verdicts if v.verdict != "not evaluable"]
    assert {v.spec.id for v in evaluable} >= {"speed_energy", "speed_range"}
    assert "energy_friction" not in {v.spec.id for v in evaluable}  # 6 and 7 were not run
    # one family: the evaluable expectations, Holm-adjusted together
    adjusted = holm([v.p_value for v in evaluable])
    assert [v.p_adjusted for v in evaluable] == adjusted
    assert all(v.family == len(evaluable) for v in evaluable)
    assert f"The family is this campaign's\n{len(evaluable)} evaluable expectations" in html
    assert "<th>p</th><th>Holm-adjusted p</th><th>Verdict</th>" in html
    rows = dict(
        re.findall(r'<tr class="expectation"[^>]*data-expectation="([^"]+)"[^>]*>(.*?)</tr>', html, re.S)
    )
    for v in verdicts:
        cells = re.findall(r'<td class="num">([^<]*)</td>', rows[v.spec.id])
        assert [c.replace("&lt;", "<") for c in cells] == [format_p(v.p_value), format_p(v.p_adjusted)], (
            v.spec.id
        )
        assert (v.verdict == "met") == (v.p_adjusted <= 0.05)
    assert {v.spec.id: v.verdict for v in verdicts if v.spec.id.startswith("speed_")} == {
        "speed_energy": "met",
        # with the simulator's between-trial spread, 3 trials a side no longer separate the half-speed
        # range from the full-speed one (the Welch interval includes 0)
        "speed_range": "not met",
    }
    assert f"{TUNED_LABEL} (lag_time_constant_s)" in rows["speed_range"]
    assert TUNED_LABEL in rows["speed_energy"]


def test_the_archive_records_the_same_p_values(knee_session: Path) -> None:
    data = load_report_data(knee_session / "archive.h5", workers=1)
    verdicts = {v.spec.id: v for v in evaluate_expectations(data).verdicts}
    with h5py.File(knee_session / "archive.h5", "r") as h5:
        for name, v in verdicts.items():
            attrs = h5[f"expectations/{name}"].attrs
            assert attrs["verdict"] == v.verdict
            for key, value in (("p_value", v.p_value), ("p_adjusted", v.p_adjusted)):
                # a not-evaluable expectation has no test: no p attribute (an archive holds no NaN to compare)
                assert attrs[key] == pytest.approx(value) if math.isfinite(value) else key not in attrs
            assert attrs["family"] == v.family
        assert h5["expectations/speed_range"].attrs["depends_on_simulator"] == '["lag_time_constant_s"]'
