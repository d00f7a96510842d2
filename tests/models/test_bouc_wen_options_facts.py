"""Facts of the Bouc-Wen fit's options (options.py): every keyword of fit / fit_trials / cross_validate is
optional and names an option, and the defaults are the documented ones."""

from __future__ import annotations

import re
from dataclasses import fields

from protocol_runner.models.bouc_wen import fitting as bw_fitting
from protocol_runner.models.bouc_wen.fitting import POLISH_FTOL, FitKeywords, FitOptions, fit
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS


def test_every_keyword_is_optional_and_names_an_option() -> None:
    """A caller may give any subset of the keywords (the rest take the FitOptions defaults); the polish
    tolerances and the last-stage switch, which only the fitter and cross-validation set, are not keywords."""
    keys = set(FitKeywords.__annotations__)
    assert FitKeywords.__required_keys__ == frozenset()
    assert FitKeywords.__optional_keys__ == frozenset(keys)
    assert keys == {f.name for f in fields(FitOptions)} - {"polish_tol", "polish_ftol", "final_solve"}


def test_the_defaults_are_those_fit_documents() -> None:
    doc = fit.__doc__ or ""
    limit = int(re.search(r"max_samples_per_trial \(default (\d+)\)", doc).group(1))  # type: ignore[union-attr]
    scheme = re.search(r'scheme \(default ``"(\w+)"``\)', doc).group(1)  # type: ignore[union-attr]
    d = FitOptions()
    assert d.max_samples_per_trial == limit
    assert d.scheme == scheme
    assert d.bounds is DEFAULT_BOUNDS
    assert d.initial is None
    assert d.final_solve  # only cross-validation's held-out fits end on the turning-point copy
    # the polish on the mid-size copy stops early as the last solve after it does
    assert d.polish_ftol == POLISH_FTOL == bw_fitting.FINAL_FTOL
