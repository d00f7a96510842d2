"""scipy imported without its array-API docstring notes, in the processes a command-line session owns
(issue 20: start-up time).

scipy 1.17 decorates about 800 of its public functions with ``xp_capabilities``
(``scipy/_lib/_array_api.py``): when each module is imported, the decorator parses the function's
docstring with scipy's numpydoc parser (``FunctionDoc``) and appends a table of the array backends the
function supports. On a knee dry run that is about 0.16 s of CPU in each process that imports
scipy.signal, scipy.stats or scipy.optimize: the session (its calibration checks and brace-off
smoothing) and the analysis workers' fork server, for docstrings nobody reads there.

`skip_array_api_notes` replaces that parser, in this process only, by one that hands each docstring back
as it is (without the note); the functions themselves are untouched, and so are their results. It has
an effect only before those scipy modules are imported, and none with a scipy that has no such parser
(older or newer releases). Only the command line's session (`cli`) and the fork server
(`worker_server`) call it, never a process that merely imports this package.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable

_DECORATED = ("scipy.signal", "scipy.stats", "scipy.optimize", "scipy.linalg", "scipy.interpolate")


class _AsWritten:
    """Stands in for scipy's numpydoc parser inside ``xp_capabilities``: the note appended to its "Notes"
    is dropped and the docstring comes back as written (after the one-line signature the decorator
    strips)."""

    def __init__(self, func: Callable[..., object]) -> None:
        self._text = func.__doc__ or ""
        self._sections: dict[str, list[str]] = {}

    def __getitem__(self, section: str) -> list[str]:
        return self._sections.setdefault(section, [])

    def __str__(self) -> str:
        return "\n" + self._text


def skip_array_api_notes() -> bool:
    """Make scipy's ``xp_capabilities`` leave docstrings unparsed in this process (module docstring);
    whether it did (False: a decorated scipy module was already imported, or this scipy has no parser
    there)."""
    if any(name in sys.modules for name in _DECORATED):
        return False
    if importlib.util.find_spec("scipy._lib._array_api") is None:  # a scipy from before the notes
        return False
    _array_api = importlib.import_module("scipy._lib._array_api")
    if not isinstance(getattr(_array_api, "FunctionDoc", None), type) or not hasattr(
        _array_api, "xp_capabilities"
    ):
        return False
    setattr(_array_api, "FunctionDoc", _AsWritten)  # noqa: B010 - a module attribute mypy cannot see
    return True
