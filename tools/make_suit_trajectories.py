"""Write the SYNTHETIC whole-suit motion of protocols/suit_phase4.yaml: all 12 RSST joints together.

Not human data. One cycle is an EVA-like "walk, then reach": two gait-like strides (legs as in
tools/make_leg_trajectories.py, the arms swinging in opposition, the feet rolling and turning a little),
then a reach forward and up with the right arm (shoulder flexion and abduction, humerus rotation, the elbow
extending, the wrist turning) while the legs stand. Each part is a motion about a standing posture
multiplied by a raised-cosine envelope, so angle and speed are continuous and the cycle ends where it
began. Every excursion is chosen by hand to sit inside the joint's range (thesis Table 2) with margin, and
the script checks each joint's peak speed and acceleration against a fraction of the rig file's default
limits (120 deg/s, 2000 deg/s^2) before it writes anything.

    python tools/make_suit_trajectories.py    # rewrites protocols/trajectories/suit_walk_reach_synthetic.csv
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

RATE_HZ = 100.0
STRIDE_S = 6.0  # one gait-like stride: a real stride takes about 1.1 s, slowed for the robot's rate limit
WALK_S = 2 * STRIDE_S
REACH_S = 8.0
CYCLE_S = WALK_S + REACH_S
CYCLES = 3
MAX_SPEED_DEG_S = 0.6 * 120.0  # a margin under the rig file's default max_rate_deg_s
MAX_ACCEL_DEG_S2 = 0.25 * 2000.0  # and under its max_accel_deg_s2
OUT = Path(__file__).resolve().parents[1] / "protocols" / "trajectories"

# thesis Table 2 ranges (deg), to check the motion against
RANGES = {
    "shoulder_flexion": (-15, 180),
    "shoulder_abduction": (0, 90),
    "humerus_rotation": (-90, 90),
    "elbow_flexion": (0, 130),
    "wrist_rotation": (-90, 90),
    "hip_flexion": (0, 100),
    "hip_abduction": (0, 45),
    "thigh_rotation": (-22, 22),
    "knee_flexion": (0, 130),
    "ankle_rotation": (-20, 20),
    "ankle_flexion": (-45, 30),
    "ankle_inversion": (-20, 20),
}
# standing posture (deg), inside every range with room on both sides
STAND = {
    "shoulder_flexion": 10.0,
    "shoulder_abduction": 15.0,
    "humerus_rotation": 0.0,
    "elbow_flexion": 30.0,
    "wrist_rotation": 0.0,
    "hip_flexion": 32.0,
    "hip_abduction": 12.0,
    "thigh_rotation": 0.0,
    "knee_flexion": 20.0,
    "ankle_rotation": 0.0,
    "ankle_flexion": -3.0,
    "ankle_inversion": 0.0,
}
# the walk: per joint [(cos_k, sin_k) for k = 1, 2] in deg over one stride (phase 0 = heel strike)
WALK = {
    "shoulder_flexion": [(-12.0, 0.0), (0.0, 0.0)],  # the arm swings against the same-side leg
    "shoulder_abduction": [(0.0, 5.0), (0.0, 0.0)],
    "humerus_rotation": [(0.0, 8.0), (0.0, 0.0)],
    "elbow_flexion": [(-12.0, 0.0), (2.0, 0.0)],
    "wrist_rotation": [(0.0, 10.0), (0.0, 0.0)],
    "hip_flexion": [(14.0, 2.0), (-2.0, 1.5)],
    "hip_abduction": [(0.0, 6.0), (1.0, 0.0)],
    "thigh_rotation": [(0.0, 8.0), (0.0, -1.0)],
    "knee_flexion": [(-8.0, -22.0), (-12.0, 6.0)],
    "ankle_rotation": [(0.0, 8.0), (0.0, 0.0)],
    "ankle_flexion": [(3.0, 8.0), (-6.0, -3.0)],
    "ankle_inversion": [(0.0, 8.0), (1.0, 0.0)],
}
# the reach: the peak change from the standing posture (deg); the legs stand still
REACH = {
    "shoulder_flexion": 100.0,
    "shoulder_abduction": 20.0,
    "humerus_rotation": -25.0,
    "elbow_flexion": -20.0,
    "wrist_rotation": 40.0,
    "hip_flexion": 0.0,
    "hip_abduction": 0.0,
    "thigh_rotation": 0.0,
    "knee_flexion": 0.0,
    "ankle_rotation": 0.0,
    "ankle_flexion": 0.0,
    "ankle_inversion": 0.0,
}


def envelope(t: np.ndarray, start_s: float, length_s: float) -> np.ndarray:
    """sin^2 over [start, start + length], 0 outside: rises from 0 and returns to 0 with zero slope."""
    x = (t - start_s) / length_s
    return np.where((x >= 0) & (x <= 1), np.sin(np.pi * x) ** 2, 0.0)


def joint_deg(joint: str, t: np.ndarray) -> np.ndarray:
    local = np.mod(t, CYCLE_S)
    phase = local / STRIDE_S
    walk = sum(
        (c * np.cos(2 * np.pi * k * phase) + s * np.sin(2 * np.pi * k * phase) - c)  # 0 at heel strike
        for k, (c, s) in enumerate(WALK[joint], start=1)
    )
    walk = np.asarray(walk, dtype=float) * envelope(local, 0.0, WALK_S)
    reach = REACH[joint] * envelope(local, WALK_S, REACH_S)
    return STAND[joint] + walk + reach


def check(columns: dict[str, np.ndarray]) -> list[str]:
    """Each joint's range, peak speed and acceleration; raises if any is outside its margin."""
    stats = []
    for joint, angle in columns.items():
        lo, hi = RANGES[joint]
        speed = np.gradient(angle, 1.0 / RATE_HZ)
        accel = np.gradient(speed, 1.0 / RATE_HZ)
        if not (lo + 2 <= angle.min() and angle.max() <= hi - 2):
            raise SystemExit(
                f"{joint}: {angle.min():.1f} to {angle.max():.1f} deg leaves [{lo}, {hi}] - 2 deg"
            )
        if np.abs(speed).max() > MAX_SPEED_DEG_S or np.abs(accel).max() > MAX_ACCEL_DEG_S2:
            raise SystemExit(
                f"{joint}: peak {np.abs(speed).max():.0f} deg/s, {np.abs(accel).max():.0f} deg/s^2 over the margin"
            )
        stats.append(
            f"{joint} {angle.min():.1f} to {angle.max():.1f} deg (peak {np.abs(speed).max():.0f} deg/s)"
        )
    return stats


def main() -> None:
    t = np.arange(0.0, CYCLES * CYCLE_S, 1.0 / RATE_HZ)
    columns = {joint: joint_deg(joint, t) for joint in STAND}
    stats = check(columns)
    header = [
        f"SYNTHETIC EVA-like whole-suit motion: {CYCLES} cycles of {CYCLE_S:g} s, each two gait-like strides of "
        f"{STRIDE_S:g} s then a {REACH_S:g} s reach forward and up with the right arm, all 12 RSST joints together.",
        "NOT measured: Fourier terms and reach excursions chosen by hand about a standing posture, inside each",
        "joint's range (thesis Table 2) and slowed for the robot's rate limit. Made by",
        "tools/make_suit_trajectories.py. Replace with a recorded motion of the same columns.",
        f"{RATE_HZ:g} Hz, {t[-1] + 1 / RATE_HZ:g} s; " + "; ".join(stats) + ".",
    ]
    lines = [f"# {h}" for h in header]
    lines.append(",".join(["time_s", *columns]))
    for i in range(t.size):
        lines.append(",".join([f"{t[i]:.2f}", *(f"{v[i]:.4f}" for v in columns.values())]))
    path = OUT / "suit_walk_reach_synthetic.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {path} ({t.size} rows)")


if __name__ == "__main__":
    main()
