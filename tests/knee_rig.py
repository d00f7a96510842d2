"""The knee (RSST joint 9) as the simulator tests and benchmarks configure it.

Thesis Eq 1-3 with Table 3: angle range 0-130°, torque ±84.8 N·m; the joint is commanded on analog output
channel 8 and read on input channels 8 (angle) and 20 (torque); it parks at 20° at 30 °/s. Only the rate
and acceleration limits differ between callers (how hard a test may drive the simulated robot), so they
are required arguments.
"""

from __future__ import annotations

from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.safety import SafetyLimits

KNEE_RANGE_DEG = (0.0, 130.0)  # thesis Eq 1, Table 3
KNEE_TORQUE_LIMIT_NM = 84.8  # thesis Table 3
KNEE_PARK_DEG = 20.0
KNEE_PARK_RATE_DEG_S = 30.0


def knee_joint_config(
    *,
    max_rate_deg_s: float,
    max_accel_deg_s2: float,
    output_rate_hz: float = 100.0,
    input_rate_hz: float = 1000.0,
    **tables: CalibrationTable | None,
) -> JointConfig:
    """The knee joint with the given safety rate limits; `tables` are JointConfig's calibration tables
    (``command_table``, ``angle_table``, ``torque_table``)."""
    return JointConfig(
        name="knee",
        range_deg=KNEE_RANGE_DEG,
        torque_range_nm=(-KNEE_TORQUE_LIMIT_NM, KNEE_TORQUE_LIMIT_NM),
        output_channel=8,
        angle_input_channel=8,
        torque_input_channel=20,
        output_rate_hz=output_rate_hz,
        input_rate_hz=input_rate_hz,
        limits=SafetyLimits(
            range_deg=KNEE_RANGE_DEG,
            max_rate_deg_s=max_rate_deg_s,
            max_accel_deg_s2=max_accel_deg_s2,
            park_angle_deg=KNEE_PARK_DEG,
            park_rate_deg_s=KNEE_PARK_RATE_DEG_S,
        ),
        **tables,
    )
