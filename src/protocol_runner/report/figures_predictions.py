"""The report's prediction figures: for each declared prediction (`report.predictions`), configuration B's
measured loop and the loop the element model fitted on A predicts for it (`report.predictions`), one trial
of B, drawn on a new Figure like every report figure (`report.drawing`), where the predictions are computed
(`report.predictions.predictions`: the session's analysis workers at the end of a session)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from protocol_runner.report.drawing import ANGLE_LABEL, COLORS, TORQUE_LABEL, empty, finish, new_figure

MEASURED_COLOR = COLORS[0]
PREDICTED_COLOR = COLORS[1]
FITTED_RANGE_COLOR = "0.9"  # light grey, behind the loops


def prediction_figure(
    fit_key: int,
    predict_key: int,
    angle_deg: npt.ArrayLike,
    measured_torque_nm: npt.ArrayLike,
    predicted_torque_nm: npt.ArrayLike,
    fitted_range_deg: tuple[float, float] | None = None,
) -> str:
    """Configuration `predict_key`'s measured loop (solid, blue) and the loop the element model fitted on
    `fit_key` predicts (dashed, red), drawn in that order: the prediction over the data it is judged
    against; behind them, shaded grey, the angles the model was fitted on (`fitted_range_deg`, when given):
    where the loop leaves them, the model extrapolates."""
    fig, (ax,) = new_figure("single")
    angle = np.asarray(angle_deg, dtype=np.float64)
    if angle.size == 0:
        empty(ax, f"no element model of configuration {fit_key}")
    else:
        if fitted_range_deg is not None:
            low, high = fitted_range_deg
            ax.axvspan(low, high, color=FITTED_RANGE_COLOR, zorder=0, label=f"angles fitted on {fit_key}")
        ax.plot(
            angle,
            measured_torque_nm,
            lw=0.7,
            color=MEASURED_COLOR,
            label=f"measured, configuration {predict_key}",
        )
        ax.plot(
            angle,
            predicted_torque_nm,
            lw=0.9,
            ls="--",
            color=PREDICTED_COLOR,
            label=f"element model fitted on {fit_key}",
        )
    title = f"Configuration {predict_key} predicted from {fit_key}"
    return finish(fig, ax, ANGLE_LABEL, TORQUE_LABEL, title)
