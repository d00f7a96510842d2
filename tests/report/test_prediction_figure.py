"""The prediction figure: B's measured loop and the element model's predicted loop, both drawn, the
measurement first (solid, blue) and the prediction over it (dashed, red), A's fitted angles shaded behind,
with the caption's numbers in the report; the report's prediction table marks a model that runs beyond
the angles it was fitted on, and says what that means for it."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.colors import to_hex

from protocol_runner.report import figures
from protocol_runner.report.figures import (
    FITTED_RANGE_COLOR,
    MEASURED_COLOR,
    PREDICTED_COLOR,
    prediction_figure,
)
from protocol_runner.report.predictions import EXTRAPOLATION_SHARE, AngleRanges, ElementPrediction, Prediction


def _prediction() -> Prediction:
    t = np.linspace(0.0, 2.0 * np.pi, 200)
    angle = 60.0 - 40.0 * np.cos(t)
    measured = 0.1 * (angle - 60.0) + 2.0 * np.sign(np.sin(t))
    predicted = 0.1 * (angle - 60.0) + 1.8 * np.sign(np.sin(t))
    element = ElementPrediction(
        rmse_nm=0.2,
        energy_predicted_j=15.1,
        energy_predicted_ci95_low_j=14.0,
        energy_predicted_ci95_high_j=16.3,
        energy_measured_j=16.8,
        angle_deg=angle,
        measured_torque_nm=measured,
        predicted_torque_nm=predicted,
    )
    return Prediction(12, 14, "ranges", 0.5, 0.4, "", element)


def test_the_figure_draws_the_measured_loop_then_the_predicted_one(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    captured = []
    real = figures.to_data_uri

    def keep(fig):  # type: ignore[no-untyped-def]
        captured.append(fig)
        return real(fig)

    monkeypatch.setattr(figures, "to_data_uri", keep)
    p = _prediction()
    assert p.element is not None
    uri = prediction_figure(
        p.fit_key,
        p.predict_key,
        p.element.angle_deg,
        p.element.measured_torque_nm,
        p.element.predicted_torque_nm,
    )
    assert uri.startswith("data:image/png;base64,")
    (ax,) = captured[-1].axes
    measured, predicted = ax.get_lines()
    assert list(measured.get_xdata()) == list(p.element.angle_deg)
    assert list(measured.get_ydata()) == list(p.element.measured_torque_nm)
    assert list(predicted.get_ydata()) == list(p.element.predicted_torque_nm)
    assert to_hex(measured.get_color()) == to_hex(MEASURED_COLOR) and measured.get_linestyle() == "-"
    assert to_hex(predicted.get_color()) == to_hex(PREDICTED_COLOR) and predicted.get_linestyle() == "--"
    assert "14" in measured.get_label() and "12" in predicted.get_label()


def test_no_element_model_draws_no_curve(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    captured = []
    real = figures.to_data_uri
    monkeypatch.setattr(figures, "to_data_uri", lambda fig: captured.append(fig) or real(fig))
    prediction_figure(12, 14, [], [], [])
    (ax,) = captured[-1].axes
    assert ax.get_lines() == []


def test_the_report_shows_each_prediction_figure_with_its_energies_in_the_caption(small_archive) -> None:  # type: ignore[no-untyped-def]
    from protocol_runner.report.load import load_report_data
    from protocol_runner.report.render import render_html

    p = _prediction()
    drawn = Prediction(
        p.fit_key,
        p.predict_key,
        p.note,
        p.rmse_nm,
        p.own_rmse_nm,
        "",
        p.element,
        "data:image/png;base64,AAAA",
    )
    data = load_report_data(small_archive, verify=False)
    page = render_html(data, generated_utc="T", workers=1, predicted=lambda: (drawn,))
    start = page.index('<figure id="fig-prediction-12-14">')
    figure = page[start : page.index("</figure>", start)]
    assert '<img src="data:image/png;base64,AAAA"' in figure
    caption = figure[figure.index("<figcaption>") :]
    assert "predicted 15.10 J [95 % 14.00, 16.30], measured 16.80 J" in caption


def test_the_figure_shades_the_angles_the_model_was_fitted_on(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    captured = []
    real = figures.to_data_uri
    monkeypatch.setattr(figures, "to_data_uri", lambda fig: captured.append(fig) or real(fig))
    e = _prediction().element
    assert e is not None
    prediction_figure(12, 14, e.angle_deg, e.measured_torque_nm, e.predicted_torque_nm, (40.9, 84.5))
    (ax,) = captured[-1].axes
    (shade,) = ax.patches
    extent = shade.get_window_extent().transformed(ax.transData.inverted())
    assert (extent.x0, extent.x1) == (pytest.approx(40.9), pytest.approx(84.5))
    assert to_hex(shade.get_facecolor()) == to_hex(FITTED_RANGE_COLOR)
    assert shade.get_label() == "angles fitted on 12"


def _ranged(fit: int, predict: int, bouc_wen: AngleRanges, element: AngleRanges) -> Prediction:
    p = _prediction()
    assert p.element is not None
    return Prediction(
        fit, predict, "", 91.81, 1.0, "", replace(p.element, ranges=element), bouc_wen_ranges=bouc_wen
    )


def test_the_report_marks_and_explains_a_prediction_beyond_the_fitted_angles(small_archive) -> None:  # type: ignore[no-untyped-def]
    """12 -> 14: both models run beyond 12's angles (the Bouc-Wen model 37.0 deg, the element model
    40.4 deg): both ranges shown with how far; the Bouc-Wen RMSE marked, the element model's not (it is
    physical), and a sentence below the table says so; 10 -> 11 reaches 1.7 deg beyond a 107 deg span:
    neither marked nor explained."""
    from protocol_runner.report.load import load_report_data
    from protocol_runner.report.render import render_html

    wide = _ranged(
        12, 14, AngleRanges((-21.37, 22.15), (-58.38, 50.19)), AngleRanges((40.93, 84.48), (0.53, 109.12))
    )
    within = _ranged(
        10, 11, AngleRanges((-58.08, 48.99), (-59.75, 49.65)), AngleRanges((0.53, 107.63), (0.06, 109.53))
    )
    data = load_report_data(small_archive, verify=False)
    page = render_html(data, generated_utc="T", workers=1, predicted=lambda: (wide, within))

    def row(fit: int, predict: int) -> list[tuple[str, str]]:
        """(class, content) of each cell of the prediction's row."""
        found = re.search(rf'<tr id="prediction-{fit}-{predict}">(.*?)</tr>', page, re.S)
        assert found is not None
        return re.findall(r'<td(?: class="([^"]*)")?>(.*?)</td>', found.group(1), re.S)

    mark = ' <span class="warn">(extrapolated)</span>'
    cells = row(12, 14)
    assert cells[3] == ("num", "0.200")  # the element model's RMSE: physical, not marked
    assert cells[6] == ("num", "[40.9, 84.5] → [0.5, 109.1] extrapolated, 40.4 beyond")
    assert cells[7] == ("num", "91.810" + mark)  # the Bouc-Wen model's RMSE
    assert cells[9] == ("num warn", "[-21.4, 22.1] → [-58.4, 50.2] extrapolated, 37.0 beyond")
    cells = row(10, 11)
    assert "extrapolated" not in str(cells) and "warn" not in str(cells)
    assert cells[6][1] == "[0.5, 107.6] → [0.1, 109.5]" and cells[9][1] == "[-58.1, 49.0] → [-59.8, 49.6]"

    note = re.search(r'<p class="note" id="extrapolation-12-14">(.*?)</p>', page, re.S)
    assert note is not None
    text = note.group(1)
    assert (
        "the element model runs 40.4 deg beyond" in text and "the Bouc-Wen model runs 37.0 deg beyond" in text
    )
    assert "polynomial fitted on 12&#39;s angles and is not meant to extrapolate" in text
    assert "RMSE of 91.81 N·m (14&#39;s own fit: 1.00 N·m)" in text
    assert "element model is physical" in text and "carries over" in text
    assert 'id="extrapolation-10-11"' not in page
    assert f"by more than {EXTRAPOLATION_SHARE:.0%}".replace("%", " %") in page  # the threshold as stated
