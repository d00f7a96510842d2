"""The HTML report: sections, figures, self-containment, escaping, banners and reproducibility."""

from __future__ import annotations

import base64
import re
import struct
from html.parser import HTMLParser
from pathlib import Path

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.report.figure_plan import figure_ids
from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import SECTIONS, generate_report, render_report
from tests.report.report_archive_builder import ArchiveSpec, small_spec, write_archive

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class _Checker(HTMLParser):
    """Collects ids, <img> sources, every src/href, and unbalanced tags."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.ids: set[str] = set()
        self.images: list[str] = []
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(str(a["id"]))
        if tag == "img":
            self.images.append(str(a.get("src")))
        for name in ("src", "href"):
            if name in a:
                self.links.append(str(a[name]))
        if tag not in VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.handle_starttag(tag, attrs)
        if tag not in VOID:
            self.stack.pop()

    def handle_endtag(self, tag: str) -> None:
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1] if self.stack else 'nothing'}")
            return
        self.stack.pop()


def _parse(html: str) -> _Checker:
    checker = _Checker()
    checker.feed(html)
    checker.close()
    return checker


def _png_size(uri: str) -> tuple[int, int]:
    assert uri.startswith("data:image/png;base64,")
    raw = base64.b64decode(uri.split(",", 1)[1], validate=True)
    assert raw[:8] == PNG_SIGNATURE and raw[12:16] == b"IHDR"
    width, height = struct.unpack(">II", raw[16:24])
    return width, height


def _strip_generated(html: str) -> str:
    return re.sub(r'<span id="generated-utc">[^<]*</span>', "", html)


def test_html_parses_with_balanced_tags(small_report: str) -> None:
    checker = _parse(small_report)
    assert checker.errors == []
    assert checker.stack == []
    assert small_report.startswith("<!DOCTYPE html>")


def test_every_section_and_the_table_of_contents_are_present(small_report: str) -> None:
    checker = _parse(small_report)
    for section_id, _title in SECTIONS:
        assert section_id in checker.ids
        assert f'href="#{section_id}"' in small_report
    assert {"toc", "interruptions", "operator", "models-physical", "models-bouc-wen"} <= checker.ids
    assert {f"config-{k}" for k in (4, 5, 6, 7)} <= checker.ids
    assert {f"matrix-{k}" for k in (4, 5, 6, 7)} <= checker.ids


def test_every_expected_figure_is_an_inline_png_that_decodes(small_archive: Path, small_report: str) -> None:
    checker = _parse(small_report)
    expected = figure_ids(load_report_data(small_archive))
    per_config = {
        f"fig-config-{k}-{kind}" for k in (4, 5, 6, 7) for kind in ("hysteresis", "time", "energy", "boucwen")
    }
    assert per_config <= set(expected)
    assert {
        "fig-calibration-friction",
        "fig-comparison-friction-overlay",
        "fig-comparison-friction-energy",
    } <= set(expected)
    # the friction group changes the brake, not the fitted springs: no elastic-model figure
    assert not any(f.startswith("fig-elements-") for f in expected)
    for figure_id in expected:
        assert figure_id in checker.ids, figure_id
    assert len(checker.images) == len(expected)
    for uri in checker.images:
        width, height = _png_size(uri)
        assert width > 0 and height > 0


def test_nothing_outside_the_file_is_referenced(small_report: str) -> None:
    checker = _parse(small_report)
    for link in checker.links:
        assert link.startswith("#") or link.startswith("data:"), link
    assert not re.search(r"""\b(src|href)\s*=\s*["'](?!#|data:)""", small_report)
    assert not re.search(r"""\b(src|href)\s*=\s*(?!["'#]|data:)""", small_report)
    assert "http://" not in small_report and "https://" not in small_report
    assert "@import" not in small_report and "url(" not in small_report
    assert "<link" not in small_report and "<script src" not in small_report


def test_header_shows_the_session_and_operator_answers_escaped(small_report: str) -> None:
    assert "knee_synthetic" in small_report and "ab" * 32 in small_report
    assert "dry-run" in small_report and "<td>7</td>" in small_report  # seed
    assert "2026-11-21T10:15:00Z" in small_report
    # the checklist title contains markup characters: they are escaped, not interpreted
    assert "Fit the brace &lt;R1&gt; &amp; check bolts" in small_report
    assert "<R1>" not in small_report
    assert "SIGINT" in small_report and "resumed" in small_report
    assert "@media print" in small_report


def test_matrix_rows_show_energy_and_fit_results(small_archive: Path, small_report: str) -> None:
    data = load_report_data(small_archive)
    for cfg in data.configurations:
        row = re.search(rf'<tr id="matrix-{cfg.key}">(.*?)</tr>', small_report, re.S)
        assert row is not None
        assert f"{cfg.energy_mean_j:.2f} ± {cfg.energy_std_j:.2f}" in row.group(1)
        assert cfg.bouc_wen is not None and f"{cfg.bouc_wen.rmse_nm:.2f}" in row.group(1)
        assert f"{cfg.angle_max_deg:.1f}" in row.group(1)


def test_configuration_sections_say_how_the_robot_torque_was_removed(small_report: str) -> None:
    section = small_report[small_report.index('id="config-4"') : small_report.index('id="config-5"')]
    assert "Robot torque removed at equal angles." in section


def test_calibration_verdicts_are_shown_with_readable_limits(small_report: str) -> None:
    calibration = small_report[small_report.index('id="calibration"') : small_report.index('id="session"')]
    assert calibration.count('class="ok">pass<') == 2
    assert "settle error ≤ 2 deg" in calibration
    assert "{&#34;" not in calibration and '{"' not in calibration  # no raw JSON dictionary


def test_complete_session_has_no_incomplete_banner(small_report: str) -> None:
    assert 'id="incomplete-banner"' not in small_report


def test_unfinished_session_report_is_produced_and_marked_incomplete(tmp_path: Path) -> None:
    spec = small_spec(status="incomplete", duration_s=9.0, calibration_fail_set="friction")
    spec.configs[-1].status = "not run"
    archive = write_archive(tmp_path / "archive.h5", spec)
    html = generate_report(archive).read_text(encoding="utf-8")
    assert 'id="incomplete-banner"' in html and "This session is incomplete" in html
    assert "Not run: no trial in the archive." in html
    assert 'class="bad">fail<' in html


def test_regenerating_gives_the_same_html_apart_from_the_generation_time(
    small_archive: Path, tmp_path: Path
) -> None:
    first = generate_report(small_archive, tmp_path / "a.html").read_text(encoding="utf-8")
    second = generate_report(small_archive, tmp_path / "b.html", workers=2).read_text(encoding="utf-8")
    assert _strip_generated(first) == _strip_generated(second)
    assert first.count('id="generated-utc"') == 1


def test_explicit_generation_time_makes_the_output_byte_identical(
    small_archive: Path, tmp_path: Path
) -> None:
    data = load_report_data(small_archive)
    a = render_report(data, tmp_path / "a.html", generated_utc="2026-11-21T12:00:00Z").read_bytes()
    b = render_report(data, tmp_path / "b.html", generated_utc="2026-11-21T12:00:00Z").read_bytes()
    assert a == b


def test_default_output_is_report_html_next_to_the_archive(tmp_path: Path) -> None:
    archive = write_archive(tmp_path / "archive.h5", small_spec(duration_s=9.0))
    assert generate_report(tmp_path) == tmp_path / "report.html"
    assert (tmp_path / "report.html").stat().st_size > 0
    assert not list(tmp_path.glob("*.partial"))
    assert archive.exists()


def test_output_into_a_missing_directory_is_invalid_input(small_archive: Path, tmp_path: Path) -> None:
    with pytest.raises(InvalidInput, match="does not exist"):
        generate_report(small_archive, tmp_path / "missing" / "report.html")


def test_reference_section_says_when_there_is_no_reference(small_report: str) -> None:
    assert 'id="reference-none"' in small_report
    assert 'id="fig-reference"' not in small_report


def test_archived_reference_is_drawn_alone_and_on_every_comparison_overlay(
    tmp_path: Path, monkeypatch
) -> None:
    from protocol_runner.report import figures

    spec = small_spec(duration_s=9.0, reference=True)
    archive = write_archive(tmp_path / "archive.h5", spec)
    html = generate_report(archive).read_text(encoding="utf-8")
    assert 'id="reference-none"' not in html
    assert "Schmidt EMU data" in html and 'id="fig-reference"' in html
    drawn = []
    real = figures.to_data_uri
    monkeypatch.setattr(figures, "to_data_uri", lambda fig: drawn.append(fig) or real(fig))
    data = load_report_data(archive)
    comp = next(c for c in data.comparisons if c.name == "friction")
    assert comp is not None
    figures.comparison_overlay_figure(data, comp)
    labels = [line.get_label() for line in drawn[-1].axes[0].get_lines()]
    assert labels.count("Schmidt EMU data") == 1 and len(labels) == 5  # four loops and the reference


def test_reference_file_given_at_generation_is_plotted(small_archive: Path, tmp_path: Path) -> None:
    ref = tmp_path / "emu.csv"
    ref.write_text("angle_deg,torque_nm\n" + "\n".join(f"{a},{0.2 * (a - 20):.3f}" for a in range(5, 106, 5)))
    html = generate_report(small_archive, tmp_path / "r.html", reference=ref).read_text(encoding="utf-8")
    assert 'id="reference-none"' not in html and "emu.csv" in html and 'id="fig-reference"' in html


def test_the_same_configurations_compared_twice_are_drawn_once(tmp_path: Path) -> None:
    spec = small_spec(duration_s=9.0)
    spec.extra_comparisons = {
        "energy_friction": ("friction", "5.7.2", "Energy loss vs friction", (4, 5, 6, 7))
    }
    html = generate_report(write_archive(tmp_path / "archive.h5", spec)).read_text(encoding="utf-8")
    assert 'id="fig-comparison-friction-overlay"' in html
    assert "fig-comparison-energy-friction" not in html


def test_report_file_gets_ordinary_permissions(small_archive: Path, tmp_path: Path) -> None:
    import os

    umask = os.umask(0)
    os.umask(umask)
    out = generate_report(small_archive, tmp_path / "report.html")
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


def test_aborted_session_without_configurations_still_reports(tmp_path: Path) -> None:
    spec = ArchiveSpec(configs=[], status="aborted", duration_s=5.0)
    html = generate_report(write_archive(tmp_path / "archive.h5", spec)).read_text(encoding="utf-8")
    assert "This session is aborted" in html
    assert _parse(html).errors == []
    assert "<img" not in html and "Figure not drawn" not in html
    assert "No declared comparison has data in this archive." in html


def test_each_configuration_shows_its_output_loop_timing(small_report: str) -> None:
    # tick jitter is measured per trial, stored in the archive and shown in the report
    import re

    timings = re.findall(
        r'<span class="loop-timing">Output loop, trial (\d+): tick lateness p99\s+([0-9.]+) ms', small_report
    )
    assert timings, "no loop timing in the report"
    # the test archive records a p99 lateness of exactly 0 s for every trial (report_archive_builder.py)
    assert [float(ms) for _, ms in timings] == [0.0] * len(timings)


def test_generated_sentences_do_not_run_together(small_report: str) -> None:
    body = small_report[small_report.index("<main>") : small_report.index("</main>")]
    body = re.sub(r"<pre.*?</pre>|<code>.*?</code>|<figure.*?</figure>", " ", body, flags=re.S)
    text = re.sub(r"<[^>]+>", "", body)
    # "18 cycles.Robot torque ..." was printed before: a full stop directly followed by a capital
    assert re.findall(r"[a-z)]\.[A-Z]", text) == []
    assert "cycles. Robot torque removed" in re.sub(r"\s+", " ", text)


def test_summary_comes_first_with_trial_intervals(small_report: str) -> None:
    main = small_report[small_report.index("<main>") :]
    assert main.index('id="summary"') < main.index('id="configurations"') < main.index('id="session"')
    row = re.search(r'<tr id="headline-4"[^>]*>(.*?)</tr>', small_report, re.S)
    assert row is not None
    cells = re.findall(r"<td[^>]*>(.*?)</td>", row.group(1), re.S)
    assert cells[2] == "friction 0"  # what sets it apart in its set: the factor that varies there
    assert cells[3] == "2 of 2"  # trials analysed, of those recorded: the experimental unit
    assert re.fullmatch(r"\[\d+\.\d\d, \d+\.\d\d\]", cells[6]), cells[6]


def test_test_matrix_has_one_column_per_declared_factor_with_level_and_quantities(small_report: str) -> None:
    from tests.report.report_archive_builder import FACTORS

    head = re.search(r'<table class="matrix">\s*<tr>(.*?)</tr>', small_report, re.S)
    assert head is not None
    columns = re.findall(r"<th>(.*?)</th>", head.group(1))
    assert columns[3 : 4 + len(FACTORS)] == ["Trajectory", *FACTORS]
    row = re.search(r'<tr id="matrix-7">(.*?)</tr>', small_report, re.S)
    assert row is not None
    assert "3 (friction 6.25 N·m, screw 1.25 turns)" in row.group(1)
    assert "R3 (range 0–130 deg)" in row.group(1)
