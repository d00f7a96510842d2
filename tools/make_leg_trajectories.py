"""Write the SYNTHETIC right-leg trajectories of protocols/leg_phase2.yaml (hip, knee, ankle flexion).

Not human data. Each gait-like file is a short Fourier series per joint, its coefficients chosen by hand
so that one cycle has the familiar shape and the commonly reported sagittal excursions of normal level
walking (hip about 30 deg, knee about 60 deg with its small loading-response bump, ankle about 30 deg),
then offset into the RSST's joint ranges (thesis Table 2: hip 0-100, knee 0-130, ankle -45-30 deg) and
slowed down so the robot's rate limit holds (a real stride takes about 1.1 s; the robot's cycle here
takes 6 s or 4 s). The sit-to-stand-like file moves all three joints from a seated posture to standing
and back with raised-cosine ramps. Nothing is fitted to any dataset.

    python tools/make_leg_trajectories.py      # rewrites protocols/trajectories/leg_*_synthetic.csv
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

RATE_HZ = 100.0
OUT = Path(__file__).resolve().parents[1] / "protocols" / "trajectories"

# (mean, [(cos_k, sin_k) for k = 1, 2, 3]) in degrees of one gait cycle, phase 0 = heel strike
GAIT = {
    "hip_flexion": (20.0, [(14.0, 2.0), (-2.0, 1.5), (0.5, -0.5)]),
    "knee_flexion": (27.0, [(-8.0, -22.0), (-12.0, 6.0), (3.0, 3.0)]),
    "ankle_flexion": (-3.0, [(3.0, 8.0), (-6.0, -3.0), (1.5, 2.5)]),
}
# seated -> standing (deg); the RSST's hip 0 deg is the standing posture
SIT = {"hip_flexion": 80.0, "knee_flexion": 90.0, "ankle_flexion": 12.0}
STAND = {"hip_flexion": 8.0, "knee_flexion": 8.0, "ankle_flexion": 0.0}


def gait_deg(joint: str, phase: np.ndarray) -> np.ndarray:
    mean, terms = GAIT[joint]
    out = np.full_like(phase, mean)
    for k, (c, s) in enumerate(terms, start=1):
        out += c * np.cos(2 * np.pi * k * phase) + s * np.sin(2 * np.pi * k * phase)
    return out


def ramp(t: np.ndarray, t0: float, length: float) -> np.ndarray:
    """0 before t0, 1 after t0 + length, a raised cosine between."""
    x = np.clip((t - t0) / length, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def sit_to_stand_deg(joint: str, t: np.ndarray, cycle_s: float, move_s: float) -> np.ndarray:
    """Seated (hold), rise over move_s, stand (hold), sit over move_s; repeated every cycle_s."""
    local = np.mod(t, cycle_s)
    hold = (cycle_s - 2 * move_s) / 2
    up = ramp(local, hold / 2, move_s)
    down = ramp(local, hold / 2 + move_s + hold, move_s)
    share = up - down
    return SIT[joint] + (STAND[joint] - SIT[joint]) * share


def write(name: str, header: list[str], t: np.ndarray, columns: dict[str, np.ndarray]) -> None:
    lines = [f"# {h}" for h in header]
    stats = ", ".join(
        f"{j} {v.min():.1f} to {v.max():.1f} deg (peak {np.max(np.abs(np.diff(v))) * RATE_HZ:.0f} deg/s)"
        for j, v in columns.items()
    )
    lines.append(f"# {RATE_HZ:g} Hz, {t[-1] + 1 / RATE_HZ:g} s; {stats}.")
    lines.append(",".join(["time_s", *columns]))
    for i in range(t.size):
        lines.append(",".join([f"{t[i]:.2f}", *(f"{v[i]:.4f}" for v in columns.values())]))
    (OUT / name).write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    for label, cycle_s in (("slow", 6.0), ("fast", 4.0)):
        cycles = 5
        t = np.arange(0.0, cycles * cycle_s, 1.0 / RATE_HZ)
        phase = t / cycle_s
        write(
            f"leg_gait_{label}_synthetic.csv",
            [
                f"SYNTHETIC gait-like right-leg motion ({label}: one cycle every {cycle_s:g} s, {cycles} cycles).",
                "NOT measured: a three-term Fourier series per joint, coefficients chosen by hand to give the",
                "commonly reported sagittal shape and excursions of normal level walking (hip ~30, knee ~60,",
                "ankle ~30 deg), offset into the RSST ranges and slowed for the robot's rate limit.",
                "Made by tools/make_leg_trajectories.py. Replace with a recorded motion of the same columns.",
            ],
            t,
            {j: gait_deg(j, phase) for j in GAIT},
        )
    cycle_s, move_s, cycles = 24.0, 8.0, 2
    t = np.arange(0.0, cycles * cycle_s, 1.0 / RATE_HZ)
    write(
        "leg_sit_to_stand_synthetic.csv",
        [
            f"SYNTHETIC sit-to-stand-like right-leg motion: seated, rise over {move_s:g} s, stand, sit over "
            f"{move_s:g} s; {cycles} cycles of {cycle_s:g} s.",
            "NOT measured: raised-cosine moves between a seated posture (hip 80, knee 90, ankle 12 deg) and",
            "standing (hip 8, knee 8, ankle 0 deg), all joints together. Made by tools/make_leg_trajectories.py.",
        ],
        t,
        {j: sit_to_stand_deg(j, t, cycle_s, move_s) for j in SIT},
    )


if __name__ == "__main__":
    main()
