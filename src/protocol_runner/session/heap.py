"""The garbage collector while a command-line session starts (issue 20).

Start-up creates hundreds of thousands of objects that live as long as the process: modules, classes,
compiled kernels, the protocol and its plan. CPython's cyclic collector, triggered by the allocations,
walks them all again and again while they are created (four full collections in the session process and two
in the fork server took ~0.33 s of CPU of a knee dry run, on a machine whose two cores are both busy from
the first trial on). So a command-line session pauses the collector while it imports and plans
(`pause`), and once start-up is over moves everything alive into the collector's permanent generation
and resumes it (`settle`): later collections walk only the objects made since. The analysis workers'
fork server does the same (forked while paused, it settles after its warm-up, `worker_warm.py`), so the
workers it forks inherit a settled heap and share its memory pages untouched.

Nothing is lost: an object that becomes garbage is still freed by reference counting at once; only
reference cycles among start-up objects would stay (the collector is resumed, not left off). Only the
command line's own process does this (`commands._command_line`): a program calling `run` in its own
process (a test, a notebook) keeps its collector as it is.
"""

from __future__ import annotations

import gc

_PAUSED: list[bool] = []


def pause() -> None:
    """Stop automatic collections until `settle` (a no-op if the collector is already off)."""
    if gc.isenabled():
        gc.disable()
        _PAUSED.append(True)


def settle() -> None:
    """Move every object alive now into the permanent generation, then resume collections if `pause`
    stopped them."""
    gc.freeze()
    if _PAUSED:
        _PAUSED.clear()
        gc.enable()
