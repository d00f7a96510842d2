"""`render_html` with figures drawn elsewhere (the session's workers) renders the page while they draw and
puts the images in their places afterwards: the text must be exactly that of a render with the
images, and a missing figure must be reported as a render with it missing reports it."""

from __future__ import annotations

from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st
from markupsafe import escape

from protocol_runner.report import render
from protocol_runner.report.figure_plan import Drawn, assemble_figures
from protocol_runner.report.figures import draw_figures
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import ReportData


def _no_predictions() -> tuple[()]:
    return ()


def test_a_page_rendered_while_the_figures_are_drawn_elsewhere_is_the_page_rendered_with_them(
    small_archive: Path,
) -> None:
    data = load_report_data(small_archive, verify=False)
    here = render.render_html(data, generated_utc="T", workers=1, predicted=_no_predictions)
    elsewhere = render.render_html(
        data, generated_utc="T", workers=1, draw=draw_figures, predicted=_no_predictions
    )
    assert elsewhere == here
    assert "@@figure-" not in elsewhere and elsewhere.count("data:image/png;base64,") >= 5


def test_a_figure_the_workers_could_not_draw_is_reported_missing_as_without_them(small_archive: Path) -> None:
    data = load_report_data(small_archive, verify=False)

    def one_fails(d: ReportData, ids: list[str]) -> list[Drawn]:
        drawn = draw_figures(d, ids)
        return [(drawn[0][0], None, "the worker failed"), *drawn[1:]]

    page = render.render_html(data, generated_utc="T", workers=1, draw=one_fails, predicted=_no_predictions)
    figures = assemble_figures(data, 1, draw=one_fails, here=render._draw_here)
    assert figures.missing and page == render._render(data, figures, "T", _no_predictions)
    assert "Figure not drawn: the worker failed." in page


@settings(max_examples=300, deadline=None)
@given(
    st.text(alphabet=st.characters(codec="utf-8"), max_size=40)
    | st.from_regex(r"data:image/png;base64,[A-Za-z0-9+/=]*", fullmatch=True)
)
def test_needs_escaping_is_whether_autoescape_would_change_the_text(text: str) -> None:
    """The page's images are put in place unescaped only when escaping would not change them: the quick
    check is exactly markupsafe's (which builds the escaped copy of every image, megabytes, to compare)."""
    assert render._needs_escaping(text) == (str(escape(text)) != text)


def test_an_image_that_escaping_would_change_is_rendered_through_the_template(small_archive: Path) -> None:
    """A figure whose text escaping changes (never a data URI, but checked) makes the page a full render,
    where the template escapes it, as a render with that figure gives."""
    data = load_report_data(small_archive, verify=False)

    def odd(d: ReportData, ids: list[str]) -> list[Drawn]:
        drawn = draw_figures(d, ids)
        return [(drawn[0][0], 'data:x,"<&>', None), *drawn[1:]]

    page = render.render_html(data, generated_utc="T", workers=1, draw=odd, predicted=_no_predictions)
    figures = assemble_figures(data, 1, draw=odd, here=render._draw_here)
    assert page == render._render(data, figures, "T", _no_predictions)
    assert "data:x,&#34;&lt;&amp;&gt;" in page
