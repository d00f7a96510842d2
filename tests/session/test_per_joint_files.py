"""The session stores every file a trajectory reads, the files of a `per_joint` trajectory's entries
included: its trials read them from the session's copy of the protocol."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.session.setup import create_session

from ..multi.test_multi_protocol import LEG_TEXT

REPO = Path(__file__).resolve().parents[2]
SIT = "trajectories/leg_sit_to_stand_synthetic.csv"


def test_a_per_joint_trajectorys_files_are_stored_with_the_session(tmp_path: Path) -> None:
    entries = "".join(f"      {j}: {{kind: file, file: {SIT}}}\n" for j in ("hip_flexion", "knee_flexion"))
    per_joint = (
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        + entries
        + "      ankle_flexion: {kind: hold, angle_deg: 0, duration_s: 47.99}"
    )
    folder = tmp_path / "campaign"
    folder.mkdir()
    shutil.copytree(REPO / "protocols" / "trajectories", folder / "trajectories")  # inside its folder
    path = folder / "leg.yaml"
    path.write_text(
        LEG_TEXT.replace(f"  sit_to_stand: {{kind: file, file: {SIT}}}", per_joint), encoding="utf-8"
    )
    session = tmp_path / "session"
    info = create_session(session, load_protocol(path), mode="dry-run", seed=7, only=(3,), realtime=False)
    assert (session / "protocol" / SIT).is_file()
    assert SIT in info.files_sha256
    assert SIT in json.loads((session / "session.json").read_text(encoding="utf-8"))["files_sha256"]
