"""The overlaid loops of one matched pair of configurations (session A against session B)."""

from __future__ import annotations

from matplotlib.figure import Figure

from protocol_runner.report.drawing import to_data_uri
from protocol_runner.report.model import Configuration


def overlay_figure(a: Configuration, b: Configuration) -> str | None:
    """Brace torque against angle, every processed trial of A (blue) and B (red); None without data."""
    if not (a.has_data or b.has_data):
        return None
    fig = Figure(figsize=(4.6, 3.3))
    ax = fig.add_axes((0.14, 0.14, 0.82, 0.76))
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
    ax.set_xlabel("Angle (deg)")
    ax.set_ylabel("Torque (N·m)")
    ax.legend(loc="best", fontsize="small")
    return to_data_uri(fig)
