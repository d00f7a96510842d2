"""A short seeded knee dry run for tests that need a real session: knee_phase1 as shipped with three periods
per trial and the Bouc-Wen fit off (the statistics and verdicts are what these tests read)."""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

import yaml

from protocol_runner.commands import run

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"


def short_knee_session(root: Path, only: Sequence[int] | None = None) -> Path:
    """Dry-run the shortened knee campaign (`only`: those configurations) under `root`; its session folder."""
    folder = root / "protocol"
    folder.mkdir()
    doc = yaml.safe_load((PROTOCOLS / "knee_phase1.yaml").read_text(encoding="utf-8"))
    doc["trajectories"]["sine"]["periods"] = 3
    doc["fits"] = {"bouc_wen": {"enabled": False}}
    for sub in ("calibration", "trajectories"):
        if (PROTOCOLS / sub).is_dir():
            shutil.copytree(PROTOCOLS / sub, folder / sub)
    path = folder / "knee_phase1.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    session = root / "session"
    code = run(
        str(path),
        dry_run=True,
        session=session,
        seed=7,
        yes=True,
        only=list(only) if only is not None else None,
        realtime=False,
        quiet=True,
    )
    assert code == 0
    return session
