"""The report shows only what the campaign declares: sources cited by the protocol (never the knee thesis by
default), the expectations' section column only when used, nothing fitted where a fit does not apply, a
readable session log, and Bouc-Wen parameters with their units."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from protocol_runner.report.load import _parse_event, load_report_data
from protocol_runner.report.render import render_html
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

SOURCE_WORDS = re.compile(r"thesis|Figures? \d|Appendix|Chapter \d|Eq \d")

CITED = """name: knee_synthetic
joint: knee_flexion
report:
  citations:
    configurations: "thesis Appendix B"
    energy: "thesis Figures 41-46"
    models: "thesis Chapter 6"
    bouc_wen: "thesis §6.2, Figures 57-58"
    matrix: "thesis Appendix A, Table 5"
"""


def _visible(html: str) -> str:
    """The page without the protocol text as run (which quotes the YAML, comments included)."""
    return re.sub(r'<pre class="protocol">.*?</pre>', "", html, flags=re.S)


def _section(html: str, start: str, end: str) -> str:
    begin = html.index(start)
    return html[begin : html.index(end, begin)]


def test_a_protocol_that_cites_nothing_gets_no_source_reference(small_report: str) -> None:
    # the synthetic archive's protocol declares no report.citations: no thesis figure, chapter or equation
    assert SOURCE_WORDS.findall(_visible(small_report)) == []
    assert "<h2>Models</h2>" in small_report


def test_each_citation_is_printed_beside_its_part(small_archive: Path) -> None:
    data = dataclasses.replace(load_report_data(small_archive), protocol_text=CITED)
    html = _visible(render_html(data, generated_utc="2026-01-01T00:00:00Z", workers=1))
    assert "<h2>Models (thesis Chapter 6)</h2>" in html
    configurations = _section(html, 'id="configurations"', 'id="config-4"')
    assert "every trial (as thesis Appendix B)" in configurations
    assert "quantity (as thesis Figures 41-46)." in _section(html, 'id="energy-loss"', 'id="reference"')
    assert "torque per sample (as thesis §6.2, Figures 57-58)." in html
    assert "The test matrix as run (as thesis Appendix A, Table 5):" in html
    # a part the protocol does not cite stays bare
    assert "trial of each overlaid." in html
    assert "Figures 32-37" not in html and "Figure 38" not in html


def _expectations_table(protocol_text: str, archive: Path) -> str:
    data = dataclasses.replace(load_report_data(archive), protocol_text=protocol_text)
    html = render_html(data, generated_utc="2026-01-01T00:00:00Z", workers=1)
    return _section(html, '<table class="expectations">', '<h3 id="headline">')


EXPECTATION = """  - id: {id}
    text: "more friction loses more per cycle"
{section}    metric: energy_per_cycle
    relation: increasing
    configurations: [4, 5, 6, 7]
"""


def test_section_column_appears_only_when_an_expectation_has_a_section(small_archive: Path) -> None:
    head = "name: knee_synthetic\njoint: knee_flexion\nexpectations:\n"
    bare = head + EXPECTATION.format(id="a", section="")
    table = _expectations_table(bare, small_archive)
    # statement, evidence, p, Holm-adjusted p, verdict
    assert "<th>§</th>" not in table and table.count("<td") == 5
    with_section = bare + EXPECTATION.format(id="b", section='    section: "5.3"\n')
    table = _expectations_table(with_section, small_archive)
    assert "<th>§</th>" in table and "<td>5.3</td>" in table
    assert table.count("<td") == 12  # both rows keep six cells, the first with an empty section


def test_a_fit_that_does_not_apply_lists_nothing_fitted_with_its_reason(tmp_path: Path) -> None:
    # configuration 17 (K0) has no spring: its element fit does not apply; 14 (K2) has one
    spec = ArchiveSpec(configs=[ConfigSpec(key=k, n_trials=1) for k in (14, 17)], duration_s=9.0)
    data = load_report_data(write_archive(tmp_path / "a.h5", spec))
    fit17 = data.configuration(17).element_fit
    assert fit17 is not None and not fit17.applicable and fit17.elements  # the device still has its spring
    html = render_html(data, generated_utc="2026-01-01T00:00:00Z", workers=1)
    row17 = re.search(r'<tr id="elements-17".*?</tr>', html, flags=re.S)
    row14 = re.search(r'<tr id="elements-14".*?</tr>', html, flags=re.S)
    assert row17 is not None and row14 is not None
    reason = fit17.reason.replace("not applicable: ", "")
    assert f"Nothing fitted: {reason}." in row17.group(0)
    assert not any(e.name in row17.group(0) for e in fit17.elements)
    assert "(lever spring)" in row14.group(0)


def test_session_log_reads_records_as_text_and_drops_empty_ones() -> None:
    empty = '{"t_utc": "2026-01-01T00:00:00Z", "kind": "referenced_files", "detail": "{}"}'
    assert _parse_event(empty) is None
    sha = "ab" * 32
    files = '{"t_utc": "t", "kind": "referenced_files", "detail": "{\\"traj/gait.csv\\": \\"' + sha + '\\"}"}'
    event = _parse_event(files)
    assert event is not None and event.detail == "traj/gait.csv: sha256 abababababab…"
    plain = _parse_event('{"t_utc": "t", "kind": "finished", "detail": "174 steps run"}')
    assert plain is not None and plain.detail == "174 steps run"


def test_bouc_wen_parameters_carry_their_units(small_report: str) -> None:
    table = _section(small_report, '<table class="bouc-wen">', "</table>")
    assert '<th rowspan="2">A (N·m/deg)</th>' in table
    assert "β1 – β6 (N·m<sup>1−n</sup>/deg)" in table
    # each estimate shows its 95 % interval (or "unidentified") on a second line of the same cell, never a ±
    assert re.search(
        r'<td class="num">-?\d+\.\d{4}<br><span class="se">\[-?\d+\.\d{4},<br>-?\d+\.\d{4}\]</span></td>',
        table,
    )
    assert "±" not in table
