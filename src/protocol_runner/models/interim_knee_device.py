"""INTERIM (issue 11, helper ELEM) — delete when the protocol declares its device (helper PROTO's branch).

Until protocols/knee_phase1.yaml lists the knee brace as elements and the rig file gives the knee joint's
`simulator:` values, the dry run and the processing build the knee brace from the old fixed settings with
the values the simulator had built in. These are knee facts and must not outlive the merge.
"""

from __future__ import annotations

from collections.abc import Sequence

KNEE_SIMULATOR = {
    "lag_time_constant_s": 0.17,
    "gravity_torque_max_nm": 35.5,
    "robot_friction_nm": 2.5,
    "robot_viscous_nm_per_deg_s": 0.03,
}
_SMOOTHING = {"transition_deg": 2.0, "static_excess_ratio": 0.3, "stribeck_speed_deg_s": 20.0}
_GEOMETRY = {"a_m": 0.03, "b_m": 0.19, "c_m": 0.055, "alpha_deg": 20.0, "preload_step_deg": 2.73, "count": 2}

Device = list[tuple[str, str, dict[str, object]]]


def lever_spring(stiffness_n_per_mm: float, preload_position: int) -> Device:
    params = {
        "stiffness_n_per_mm": stiffness_n_per_mm,
        "preload_index": preload_position,
        "max_preload_mm": 32.0,
    }
    return [("springs", "lever_spring", {**params, **_GEOMETRY})]


def knee_brace(
    rom_deg: Sequence[float], friction_nm: float, stiffness_n_per_mm: float, preload_position: int
) -> Device:
    return [
        ("stops", "rom_stops", {"range_deg": list(rom_deg), "slack_deg": 13.0, "slack_stiffness_nm_per_deg": 0.05,
                                "stop_stiffness_nm_per_deg": 40.0}),
        ("brake", "coulomb_brake", {"torque_nm": friction_nm, **_SMOOTHING}),
        ("hinge", "coulomb_brake", {"torque_nm": 0.75, **_SMOOTHING}),
        *lever_spring(stiffness_n_per_mm, preload_position),
        ("cuff", "cuff_shift", {"angle_deg": 35.0, "width_deg": 5.0, "torque_nm": 5.0, "reference_speed_deg_s": 50.0,
                                "reference_force_n": 200.0}),
    ]  # fmt: skip
