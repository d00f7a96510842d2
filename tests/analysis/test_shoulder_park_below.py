"""A shoulder campaign parked at the rig's own angle (0 deg) with its motion starting at 20 deg: every trial
arrives lagging after the approach. The brace-off twins are scaled on the cycles (not on the first sample)
and driven with the servo lag inverted, so a configuration with no device loses (almost) nothing, at both
speeds, while the viscous damper's loss stays."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from protocol_runner.cli import main

SHOULDER = Path(__file__).with_name("shoulder_park_below.yaml")


def test_no_device_loses_under_a_tenth_of_a_joule_per_cycle(tmp_path: Path) -> None:
    session = tmp_path / "shoulder"
    assert main([str(SHOULDER), "--dry-run", "--seed", "7", "--session", str(session)]) == 0
    with h5py.File(session / "archive.h5") as f:
        energy = {
            k: float(np.mean(f[f"configurations/config_{k:02d}/joints/shoulder_flexion/energy_loss_j"][()]))
            for k in (1, 2, 3, 4)
        }
        for k in (1, 2, 3, 4):  # every twin matched its brace-on cycles within the 0.1 deg tolerance
            scaling = f[f"configurations/config_{k:02d}/trials/1/brace_off/joints/shoulder_flexion/scaling"]
            assert bool(scaling.attrs["converged"])
            assert float(np.min(scaling["range_error_deg"][()])) <= 0.1
    # 1, 2: no device at 20 and 40 deg/s; 3, 4: the 0.05 N*m*s/deg damper (2.1 and 4.2 J on a sharp triangle)
    assert abs(energy[1]) < 0.1 and abs(energy[2]) < 0.1
    assert 1.5 < energy[3] < 2.2 and 2.8 < energy[4] < 4.3
