"""A new session runs the protocol it was created from without reading it back (the start-up read
and checked it twice); what it runs must be exactly what a resume reads back from the session's copy."""

from __future__ import annotations

from pathlib import Path

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.only import KeySelection
from protocol_runner.protocol.plan import expand
from protocol_runner.session.setup import create_session, created_session_protocol, load_session_protocol

from .test_rig_provenance import lab_campaign


def test_the_created_session_protocol_is_the_one_read_back_from_the_session(tmp_path: Path) -> None:
    loaded = load_protocol(lab_campaign(tmp_path / "campaign"))  # a lab rig file and trajectory files
    planned = expand(loaded, only=KeySelection(((3, 5),)))
    session = tmp_path / "session"
    info = create_session(session, loaded, mode="dry-run", seed=1, only=planned.only, realtime=False)

    created = created_session_protocol(session, info, loaded)
    read_back, plan, changed = load_session_protocol(session, info, force=False)

    assert not changed
    assert created == read_back  # protocol, path, text, sha256
    assert created.protocol.model_dump() == read_back.protocol.model_dump()
    assert (created.shown, created.lines, created.rig_source) == (
        read_back.shown,
        read_back.lines,
        read_back.rig_source,
    )
    assert created.base_dir == session / "protocol"
    assert planned == plan and planned.only == (3, 4, 5)
