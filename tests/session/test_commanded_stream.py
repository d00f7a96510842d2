"""The archive records every sample a dry run commanded - approach, trajectory and exit, with its time - and
every one of them is inside the protocol's envelope, junctions included."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from protocol_runner.hardware.stream import APPROACH, EXIT, TRAJECTORY
from protocol_runner.protocol.loader import find_protocol, load_protocol


def _motion_groups(f: h5py.File) -> list[h5py.Group]:
    found: list[h5py.Group] = []

    def visit(name: str, obj: object) -> None:
        if isinstance(obj, h5py.Group) and "command_deg" in obj and "time_s" in obj:
            found.append(obj)

    f.visititems(visit)
    return found


def test_every_commanded_sample_is_archived_with_its_time_and_inside_the_envelope(
    reference_archive: Path,
) -> None:
    safety = load_protocol(find_protocol("knee_phase1.yaml")).protocol.rig.safety
    with h5py.File(reference_archive, "r") as f:
        groups = _motion_groups(f)
        kinds = {g.name.split("/")[1] for g in groups}
        assert kinds == {"calibration", "configurations"} and len(groups) >= 8
        for g in groups:
            s = g["stream"]
            deg, t, seg = s["command_deg"][:], s["command_time_s"][:], s["segment"][:]
            assert json.loads(s.attrs["segments"])[str(TRAJECTORY)] == "trajectory"
            assert s["command_time_s"].attrs["units"] == "s" and s["command_deg"].attrs["units"] == "deg"
            # the trajectory part is the trial's own command, on the trial's time base
            np.testing.assert_array_equal(deg[seg == TRAJECTORY], g["command_deg"][:])
            np.testing.assert_allclose(t[seg == TRAJECTORY], g["command_time_s"][:], atol=1e-12)
            assert list(np.unique(seg)) == [APPROACH, TRAJECTORY, EXIT], g.name
            assert t[0] < 0.0 and np.all(np.diff(t) > 0)
            # from the park angle at rest back to it at rest, within range, rate and acceleration
            assert deg[0] == safety.park_angle_deg and deg[-1] == safety.park_angle_deg
            held = np.concatenate([[deg[0]], deg, [deg[-1]]])
            rate_hz = 1.0 / float(np.median(np.diff(t)))
            assert np.max(np.abs(np.diff(held))) * rate_hz <= safety.max_rate_deg_s * (1 + 1e-9), g.name
            accel = np.max(np.abs(np.diff(held, 2))) * rate_hz**2
            assert accel <= safety.max_accel_deg_s2 * (1 + 1e-9), (g.name, accel)
