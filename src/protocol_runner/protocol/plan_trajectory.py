"""What a trial commands, as the plan records it: the `Trajectory` (JSON shape of the plan contract,
protocol/trajectory_record.py) and how a configuration's, or the calibration step's, is derived from the
protocol.

`build_trajectory` resolves the bound fields of a named `TrajectorySpec` (protocol/trajectory_specs.py) and
has its kind build the `Trajectory`; its JSON is {"profile": kind, "name": name, the kind's fields resolved,
"duration_s"} (a sinusoid also keeps mean_deg, amplitude_deg and period_s; a file keeps `source`, the
file as written, plus the angle `column` read and its `origin`). `protocol/sampling.py` samples any of
them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ..errors import InvalidInput
from ..hardware.safety import SafetyLimits
from .trajectory_record import Trajectory
from .trajectory_specs import Quantity, TrajectorySpec


def build_trajectory(
    name: str,
    spec: TrajectorySpec,
    values: Mapping[str, Quantity],
    base_dir: Path,
    *,
    joint: str | None = None,
    limits: SafetyLimits | None = None,
) -> Trajectory:
    """The trajectory `name` commands, with each bound field of `spec` taking its value from `values`
    (field -> the resolved factor quantity). A file is read from `base_dir` (its angle column: `joint`'s,
    else `angle_deg`); a triangle without `corner_accel_deg_s2` turns at `limits.max_accel_deg_s2`.
    `InvalidInput` names the trajectory and the field."""
    return spec.build(name, _resolve(name, spec, values), base_dir, joint, limits)


def _resolve(name: str, spec: TrajectorySpec, values: Mapping[str, Quantity]) -> dict[str, Quantity | None]:
    """Each bindable field's value: its constant, or the resolved value of its binding (checked)."""
    out: dict[str, Quantity | None] = {}
    for field in type(spec).bindable:
        written = getattr(spec, field)
        if not isinstance(written, str):
            out[field] = written
            continue
        if field not in values:
            raise InvalidInput(
                f"trajectory {name!r}: {field} is bound to {written} but no value was given for it"
            )
        value = values[field]
        what = f"trajectory {name!r}: {field} (bound to {written})"
        if field == "range_deg":
            if not (isinstance(value, tuple) and len(value) == 2 and value[0] < value[1]):
                raise InvalidInput(f"{what} needs a range [low, high] with low < high, got {value!r}")
        elif not isinstance(value, float | int) or isinstance(value, bool):
            raise InvalidInput(f"{what} needs a number, got {value!r}")
        elif field in ("speed_deg_s", "corner_accel_deg_s2") and not value > 0:
            raise InvalidInput(f"{what} must be greater than 0, got {value:g}")
        out[field] = value
    return out
