"""Moving the joint between trials: every move goes through the rig's safety envelope.

Each step starts and ends with the joint parked at the protocol's park angle (the rig parks after every
run, and the runner parks on any stop). Before a trajectory whose first sample is elsewhere, `approach`
drives the joint there along a ramp inside the rate and acceleration limits, so no step is ever commanded
as a jump (DESIGN.md: everything sent to hardware passes the safety envelope). The approach is not part of
the recorded trial.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from ..hardware.rig import Rig
from ..hardware.safety import parking_ramp_deg


def approach(
    rig: Rig, to_deg: float, *, where: str, stop_requested: Callable[[], bool] | None = None
) -> None:
    """Move from the park angle to `to_deg` (a trapezoidal ramp at the park rate)."""
    limits = rig.joint.limits
    start = limits.park_angle_deg
    if abs(start - to_deg) < 1e-9:
        return
    ramp = parking_ramp_deg(start, replace(limits, park_angle_deg=float(to_deg)), rig.joint.output_rate_hz)
    rig.run_trajectory(ramp, where=f"{where} (approach)", stop_requested=stop_requested)
