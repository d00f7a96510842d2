"""Human-profile configurations record their subject's motion range (issue 15 item 7), not a robot range
level."""

from __future__ import annotations

import numpy as np

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.trajectories import load_trajectory_file

from .test_plan import KNEE


def test_human_profile_configurations_record_the_motion_files_range() -> None:
    loaded = load_protocol(KNEE)
    plan = expand(loaded)
    checked = 0
    for step in plan.steps:
        settings = getattr(step, "settings", None)
        cfg_key = getattr(step, "configuration", None)
        if settings is None or cfg_key is None or getattr(step, "kind", "") != "operator_checklist":
            continue
        spec = next(c for s in loaded.protocol.sets for c in s.configurations if c.key == cfg_key)
        if spec.profile != "human":
            assert "motion file" not in settings.robot_rom
            continue
        assert spec.trajectory is not None
        motion = load_trajectory_file(
            loaded.base_dir / loaded.protocol.trajectories.human[spec.trajectory].file
        )
        assert settings.robot_rom == f"{spec.trajectory} (motion file)"
        assert settings.robot_rom_deg == (float(np.min(motion.angle_deg)), float(np.max(motion.angle_deg)))
        assert settings.robot_rom_deg != (0.0, 110.0)  # the Rr-E level the rows name
        checked += 1
    assert checked == 3  # configurations 24-26
