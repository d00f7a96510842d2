"""Preflight: everything a run checks before it creates its session folder, in one function.

`--validate`, `--plan`, a run and a resume all call `preflight`, so "valid" means "the run will start":

1. the protocol loads: YAML limits, schema, cross-field checks, and every referenced file confined to the
   protocol's folder, loaded and checked (protocol/loader.py, protocol/validate.py);
2. `--only` is checked against the matrix and the plan is expanded (protocol/plan.py);
3. every motion's complete commanded stream (approach, trajectory sampled exactly as the run samples it,
   exit, and a stop after any sample) passes the rig's safety envelope: this runs while the protocol loads
   (step 1, `protocol/stream_check.py`). Brace-off trials follow a measured brace-on output, so the rig
   checks them when they run.

A problem is an `InvalidInput` (exit 2) naming file, line and field; nothing has been written yet.
"""

from __future__ import annotations

from collections.abc import Iterable

from .protocol.loader import LoadedProtocol
from .protocol.only import KeySelection
from .protocol.plan import Plan, expand


def preflight(loaded: LoadedProtocol, only: KeySelection | Iterable[int] | None = None) -> Plan:
    """The run's checks before anything is written (module docstring); returns the plan."""
    return expand(loaded, only=only)
