"""The trajectory kinds' schema: one model per kind, told apart by `kind`; bindings are `factor.quantity`."""

from __future__ import annotations

import math

import pytest
from pydantic import TypeAdapter, ValidationError

from protocol_runner.protocol.trajectory_specs import (
    HoldSpec,
    SinusoidSpec,
    TrajectorySpec,
    TriangleSpec,
    kind_names,
    trajectory_bindings,
)

SPEC: TypeAdapter[TrajectorySpec] = TypeAdapter(TrajectorySpec)


def test_kind_selects_the_model_and_bound_fields_are_listed() -> None:
    spec = SPEC.validate_python(
        {"kind": "sinusoid", "range_deg": "robot_rom.range_deg", "speed_deg_s": 60, "periods": 8}
    )
    assert isinstance(spec, SinusoidSpec)
    assert spec.speed_deg_s == 60.0 and spec.range_deg == "robot_rom.range_deg"
    assert trajectory_bindings(spec) == {"range_deg": "robot_rom.range_deg"}
    tri = SPEC.validate_python(
        {
            "kind": "triangle",
            "range_deg": [0, 110],
            "speed_deg_s": "speed.speed_deg_s",
            "cycles": 3,
            "corner_accel_deg_s2": "stops.accel_deg_s2",
        }
    )
    assert isinstance(tri, TriangleSpec) and tri.range_deg == (0.0, 110.0)
    assert trajectory_bindings(tri) == {
        "speed_deg_s": "speed.speed_deg_s",
        "corner_accel_deg_s2": "stops.accel_deg_s2",
    }


def test_every_kind_has_a_model_and_constant_specs_have_no_bindings() -> None:
    examples: dict[str, dict[str, object]] = {
        "sinusoid": {"range_deg": [0, 90], "speed_deg_s": 60, "periods": 8},
        "triangle": {"range_deg": [0, 90], "speed_deg_s": 60, "cycles": 2},
        "file": {"file": "trajectories/subject_B_synthetic.csv"},
        "identification": {
            "range_deg": [0, 110],
            "total_s": 60,
            "repetition_s": 30,
            "initial_period_s": 8,
            "final_period_s": 3.2,
        },
        "ramped_step": {"from_deg": 20, "step_deg": 45, "ramp_s": 0.6, "hold_s": 4, "settle_s": 1},
        "hold": {"angle_deg": 45, "duration_s": 2},
        "per_joint": {"joints": {"knee_flexion": {"kind": "hold", "angle_deg": 45, "duration_s": 2}}},
    }
    assert set(examples) == set(kind_names())
    for kind, fields in examples.items():
        spec = SPEC.validate_python({"kind": kind, **fields})
        assert spec.kind == kind
        assert trajectory_bindings(spec) == {}


@pytest.mark.parametrize(
    ("doc", "field", "words"),
    [
        ({"kind": "spiral"}, None, "spiral"),
        ({"kind": "hold", "angle_deg": 3, "duration_s": 2, "speed_deg_s": 1}, "speed_deg_s", "Extra"),
        ({"kind": "hold", "angle_deg": math.nan, "duration_s": 2}, "angle_deg", "finite"),
        ({"kind": "hold", "angle_deg": 3, "duration_s": math.inf}, "duration_s", "finite"),
        ({"kind": "hold", "angle_deg": "45 deg", "duration_s": 2}, "angle_deg", "binding"),
        ({"kind": "hold", "angle_deg": True, "duration_s": 2}, "angle_deg", "number"),
        (
            {"kind": "sinusoid", "range_deg": [90, 0], "speed_deg_s": 6, "periods": 1},
            "range_deg",
            "low < high",
        ),
        (
            {"kind": "sinusoid", "range_deg": [0, 90], "speed_deg_s": -6, "periods": 1},
            "speed_deg_s",
            "greater",
        ),
        ({"kind": "triangle", "range_deg": [0, 9], "speed_deg_s": 6, "cycles": 1.3}, "cycles", "half"),
        (
            {"kind": "ramped_step", "from_deg": 0, "step_deg": 4, "ramp_s": -1, "hold_s": 1, "settle_s": 1},
            "ramp_s",
            "",
        ),
        ({"kind": "file"}, "file", "Field required"),
    ],
)
def test_bad_trajectory_specs_are_refused_naming_the_field(
    doc: dict[str, object], field: str | None, words: str
) -> None:
    with pytest.raises(ValidationError) as info:
        SPEC.validate_python(doc)
    error = info.value.errors()[0]
    if field is not None:
        assert error["loc"][-1] == field
    assert words in str(info.value)


def test_specs_are_immutable() -> None:
    spec = HoldSpec(kind="hold", angle_deg=10.0, duration_s=1.0)
    with pytest.raises(ValidationError):
        spec.angle_deg = 20.0
