"""constraints.txt, the pinned analysis environment: it pins every dependency the package declares (its
extras for the tests and development included), each pin inside the bounds pyproject.toml sets, so
`pip install -c constraints.txt '.[dev]'` reproduces the environment the tests passed with."""

from __future__ import annotations

import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]


def _pins() -> dict[str, str]:
    pins: dict[str, str] = {}
    for line in (REPO / "constraints.txt").read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, version = line.partition("==")
            assert version, f"constraints.txt: {line!r} is not pinned with =="
            pins[canonicalize_name(name)] = version
    return pins


def _declared() -> list[Requirement]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = project["optional-dependencies"]
    return [Requirement(r) for r in [*project["dependencies"], *extras["test"], *extras["dev"]]]


def test_every_declared_dependency_is_pinned_inside_its_bounds() -> None:
    pins = _pins()
    for requirement in _declared():
        name = canonicalize_name(requirement.name)
        assert name in pins, f"{requirement.name} is a dependency but constraints.txt does not pin it"
        assert requirement.specifier.contains(pins[name], prereleases=True), (
            f"constraints.txt pins {requirement.name}=={pins[name]}, outside pyproject.toml's {requirement}"
        )


def test_the_libraries_the_numbers_rely_on_have_an_upper_bound() -> None:
    bounded = {canonicalize_name(r.name) for r in _declared() if any(s.operator == "<" for s in r.specifier)}
    assert {"numpy", "scipy", "matplotlib", "h5py", "pydantic", "numba"} <= bounded
