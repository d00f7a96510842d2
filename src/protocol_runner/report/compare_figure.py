"""The overlaid loops of one matched pair of configurations (session A against session B)."""

from __future__ import annotations

from protocol_runner.report.drawing import ANGLE_LABEL, TORQUE_LABEL, legend, new_figure, style, to_data_uri
from protocol_runner.report.model import Configuration


def overlay_figure(a: Configuration, b: Configuration) -> str | None:
    """Brace torque against angle, every processed trial of A (blue) and B (red); None without data."""
    if not (a.has_data or b.has_data):
        return None
    fig, (ax,) = new_figure("single")
    for cfg, color, name in ((a, "#1f77b4", "A"), (b, "#d62728", "B")):
        first = True
        for trial in cfg.trials:
            if trial.processed is None:
                continue
            ax.plot(
                trial.processed.angle_deg,
                trial.processed.brace_torque_nm,
                color=color,
                linewidth=0.7,
                alpha=0.8,
                label=f"{name}: configuration {cfg.key}" if first else None,
            )
            first = False
    style(ax, ANGLE_LABEL, TORQUE_LABEL)
    legend(ax)
    return to_data_uri(fig)
