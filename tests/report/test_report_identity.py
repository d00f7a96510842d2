"""The report says what it is about: the protocol's title and description at the top (docs/protocol.md:
"free text shown in the report"), and for each configuration what sets it apart in its set, in the
summary table and in its heading; a hysteresis caption mentions a fitted model only where one is drawn."""

from __future__ import annotations

import re
from pathlib import Path

from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import generate_report, varying_levels
from tests.report.report_archive_builder import small_spec, write_archive

PROTOCOL = (
    "name: knee_synthetic\ntitle: Knee brake sweep <R1>\njoint: knee_flexion\n"
    "description: Four brake settings at full speed & centre preload.\n"
)


def _report(tmp_path: Path, protocol_text: str) -> str:
    archive = write_archive(tmp_path / "archive.h5", small_spec(protocol_text=protocol_text))
    return generate_report(archive, tmp_path / "report.html").read_text(encoding="utf-8")


def test_the_title_heads_the_page_and_the_description_follows(tmp_path: Path) -> None:
    page = _report(tmp_path, PROTOCOL)
    assert "<title>Knee brake sweep &lt;R1&gt; — protocol-runner report</title>" in page
    assert "<h1>Knee brake sweep &lt;R1&gt;</h1>" in page
    assert '<p class="protocol-name">Protocol <code>knee_synthetic</code></p>' in page
    assert '<p class="description">Four brake settings at full speed &amp; centre preload.</p>' in page


def test_without_a_title_the_name_heads_the_page(small_report: str) -> None:
    assert "<h1>knee_synthetic</h1>" in small_report
    assert 'class="protocol-name"' not in small_report and 'class="description"' not in small_report


def test_each_configuration_is_named_by_what_varies_in_its_set(
    small_archive: Path, small_report: str
) -> None:
    data = load_report_data(small_archive)
    varying = varying_levels(data)
    assert {c.key: varying[c.key] for c in data.configurations} == {
        c.key: f"friction {c.level('friction')}" for c in data.configurations
    }
    assert len(set(varying.values())) == len(data.configurations)  # every one told apart
    for c in data.configurations:
        heading = re.search(
            rf'<section class="config" id="config-{c.key}">\s*<h3>(.*?)</h3>', small_report, re.S
        )
        assert heading is not None and heading.group(1).endswith(f": friction {c.level('friction')}")
        row = re.search(rf'<tr id="headline-{c.key}"[^>]*>(.*?)</tr>', small_report, re.S)
        assert row is not None and f"<td>friction {c.level('friction')}</td>" in row.group(1)


def test_a_set_of_one_configuration_has_nothing_to_tell_apart(small_archive: Path) -> None:
    import dataclasses

    data = load_report_data(small_archive)
    first, *rest = data.configurations
    alone = dataclasses.replace(first, set_name="single")
    varying = varying_levels(dataclasses.replace(data, configurations=(alone, *rest)))
    assert varying[alone.key] == ""
    assert all(varying[c.key].startswith("friction ") for c in rest)


def test_the_dashed_model_is_captioned_only_where_an_elastic_fit_is_drawn(
    small_archive: Path, small_report: str
) -> None:
    data = load_report_data(small_archive)
    for c in data.configurations:
        caption = re.search(
            rf'id="fig-config-{c.key}-hysteresis".*?<figcaption>(.*?)</figcaption>', small_report, re.S
        )
        assert caption is not None
        drawn = c.element_fit is not None and c.element_fit.drawable
        assert ("dashed: fitted elastic elements" in caption.group(1)) == drawn, (c.key, caption.group(1))


def test_without_an_elastic_fit_the_caption_mentions_no_dashed_model(small_archive: Path) -> None:
    import dataclasses

    from protocol_runner.report.render import render_html

    data = load_report_data(small_archive)
    first, *rest = data.configurations
    page = render_html(
        dataclasses.replace(data, configurations=(dataclasses.replace(first, element_fit=None), *rest))
    )
    captions = {
        int(k): text
        for k, text in re.findall(
            r'id="fig-config-(\d+)-hysteresis".*?<figcaption>(.*?)</figcaption>', page, re.S
        )
    }
    assert captions[first.key] == f"Configuration {first.key}: brace torque vs angle, all trials."
    assert all("dashed: fitted elastic elements" in captions[c.key] for c in rest)
