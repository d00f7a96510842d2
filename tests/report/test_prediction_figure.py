"""The prediction figure: B's measured loop and the element model's predicted loop, both drawn, the
measurement first (solid, blue) and the prediction over it (dashed, red), with the caption's numbers in
the report."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_hex

from protocol_runner.report import drawing
from protocol_runner.report.figures_predictions import MEASURED_COLOR, PREDICTED_COLOR, prediction_figure
from protocol_runner.report.predictions import ElementPrediction, Prediction


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
    real = drawing.to_data_uri

    def keep(fig):  # type: ignore[no-untyped-def]
        captured.append(fig)
        return real(fig)

    monkeypatch.setattr(drawing, "to_data_uri", keep)
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
    real = drawing.to_data_uri
    monkeypatch.setattr(drawing, "to_data_uri", lambda fig: captured.append(fig) or real(fig))
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
