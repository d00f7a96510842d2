"""The report's prediction figures: for each declared prediction (`report.predictions`), configuration B's
measured loop and the loop the element model fitted on A predicts for it (`report.predictions`), one trial
of B, drawn on a new Figure like every report figure (`report.drawing`), where the predictions are computed
(`report.predictions.predictions`: the session's analysis workers at the end of a session)."""

from __future__ import annotations

from protocol_runner.report.drawing import ANGLE_LABEL, COLORS, TORQUE_LABEL, empty, finish, new_figure
from protocol_runner.report.predictions import Prediction

MEASURED_COLOR = COLORS[0]
PREDICTED_COLOR = COLORS[1]


def prediction_figure(p: Prediction) -> str:
    """B's measured loop (solid, blue) and the element model's predicted loop (dashed, red), drawn in
    that order: the prediction over the data it is judged against."""
    fig, (ax,) = new_figure("single")
    e = p.element
    if e is None or e.angle_deg.size == 0:
        empty(ax, f"no element model of configuration {p.fit_key}")
    else:
        ax.plot(
            e.angle_deg,
            e.measured_torque_nm,
            lw=0.7,
            color=MEASURED_COLOR,
            label=f"measured, configuration {p.predict_key}",
        )
        ax.plot(
            e.angle_deg,
            e.predicted_torque_nm,
            lw=0.9,
            ls="--",
            color=PREDICTED_COLOR,
            label=f"element model fitted on {p.fit_key}",
        )
    title = f"Configuration {p.predict_key} predicted from {p.fit_key}"
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, title)
