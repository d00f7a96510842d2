"""The knee brace (thesis §4.1, Appendix A) as composed device elements, and the knee joint's robot-side
simulator values — the test suite's copy of what protocols/knee_phase1.yaml (device) and the rig file
(the knee joint's `simulator:` mapping) give the package. Nothing in src/ defaults to these numbers.

The values are those the simulator used before the device became elements (recorded output:
tests/hardware/data/knee_brace_baseline.npz; docs/simulator.md says which thesis finding pins each).
"""

from __future__ import annotations

from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.models.spring import SpringGeometry

KNEE_SIMULATOR = {
    "lag_time_constant_s": 0.17,
    "gravity_torque_max_nm": 35.5,
    "gravity_zero_angle_deg": 0.0,
    "robot_friction_nm": 2.5,
    "robot_friction_transition_deg": 1.5,
    "robot_viscous_nm_per_deg_s": 0.03,
    "angle_noise_deg": 0.1,
    "torque_noise_nm": 0.8,
}
"""The knee joint's `simulator:` mapping (SimulatorParams field names)."""

KNEE_PARAMS = SimulatorParams(**KNEE_SIMULATOR)

KNEE_GEOMETRY = SpringGeometry(
    a_m=0.03, b_m=0.19, c_m=0.055, alpha_deg=20.0, preload_step_deg=2.73, n_springs=2
)
KNEE_MAX_PRELOAD_MM = 32.0
STIFFNESS_N_PER_MM = {"K0": 0.0, "K1": 4.4, "K2": 13.0, "K3": 20.0}  # Appendix A "Stiffness"

BRAKE_SMOOTHING = {"transition_deg": 2.0, "static_excess_ratio": 0.3, "stribeck_speed_deg_s": 20.0}
CUFF_SHIFT = {
    "angle_deg": 35.0,
    "width_deg": 5.0,
    "torque_nm": 5.0,
    "reference_speed_deg_s": 50.0,
    "reference_force_n": 200.0,
}


def lever_spring(stiffness_n_per_mm: float, preload_index: int = 3, **extra: float) -> tuple[str, str, dict]:
    params = {
        "stiffness_n_per_mm": stiffness_n_per_mm,
        "preload_index": preload_index,
        "max_preload_mm": KNEE_MAX_PRELOAD_MM,
        "a_m": KNEE_GEOMETRY.a_m,
        "b_m": KNEE_GEOMETRY.b_m,
        "c_m": KNEE_GEOMETRY.c_m,
        "alpha_deg": KNEE_GEOMETRY.alpha_deg,
        "preload_step_deg": KNEE_GEOMETRY.preload_step_deg,
        "count": KNEE_GEOMETRY.n_springs,
        **extra,
    }
    return ("springs", "lever_spring", params)


def knee_brace(
    rom_deg: tuple[float, float],
    friction_nm: float,
    stiffness_n_per_mm: float,
    preload_index: int = 3,
    *,
    cuff_shift: bool = True,
) -> list[tuple[str, str, dict]]:
    """The knee brace set up at these Appendix A levels, as (name, type, params) elements."""
    device = [
        ("stops", "rom_stops", {
            "range_deg": list(rom_deg), "slack_deg": 13.0, "slack_stiffness_nm_per_deg": 0.05,
            "stop_stiffness_nm_per_deg": 40.0,
        }),
        ("brake", "coulomb_brake", {"torque_nm": friction_nm, **BRAKE_SMOOTHING}),
        ("hinge", "coulomb_brake", {"torque_nm": 0.75, **BRAKE_SMOOTHING}),
        lever_spring(stiffness_n_per_mm, preload_index),
    ]  # fmt: skip
    if cuff_shift:
        device.append(("cuff", "cuff_shift", dict(CUFF_SHIFT)))
    return device


def spring_torque_nm(angle_deg, stiffness_n_per_mm, preload_index, **kw):  # type: ignore[no-untyped-def]
    """Eq 13-18 with the knee brace's geometry and Max_Preload unless given."""
    from protocol_runner.models import spring

    kw = {"max_preload_mm": KNEE_MAX_PRELOAD_MM, "geometry": KNEE_GEOMETRY, **kw}
    return spring.spring_torque_nm(angle_deg, stiffness_n_per_mm, preload_index, **kw)


def fit_spring_model(angle_deg, torque_nm, stiffness_n_per_mm, preload_index, **kw):  # type: ignore[no-untyped-def]
    """The element fit of the knee brace's lever spring, with its two fitted values as attributes."""
    from types import SimpleNamespace

    from protocol_runner.analysis.element_fit import fit_elements

    fit = fit_elements(angle_deg, torque_nm, [lever_spring(stiffness_n_per_mm, preload_index)], **kw)
    values = {p: v for _, p, v in fit.fitted}
    nan = float("nan")
    return SimpleNamespace(
        **{f: getattr(fit, f) for f in fit.__dataclass_fields__},
        max_preload_mm=values.get("max_preload_mm", nan),
        zero_offset_deg=values.get("zero_offset_deg", nan),
    )
