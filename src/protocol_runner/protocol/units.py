"""The unit suffixes a quantity's name must end with (docs/protocol.md "Quantities and units").

A factor level's quantities, an element's parameters and a trajectory's bindable fields all carry their
unit in their name (`friction_nm`, `speed_deg_s`, `range_deg`). A binding `"<factor>.<quantity>"` is only
accepted where the quantity's suffix equals the parameter's: a torque cannot drive a speed.
"""

from __future__ import annotations

UNIT_SUFFIXES: dict[str, str] = {
    "_nm_s_per_deg": "N*m*s/deg",
    "_nm_per_deg": "N*m/deg",
    "_nm_s_per_rad": "N*m*s/rad",
    "_nm_per_rad": "N*m/rad",
    "_n_per_mm": "N/mm",
    "_n_per_m": "N/m",
    "_deg_s2": "deg/s^2",
    "_deg_s": "deg/s",
    "_deg": "deg",
    "_rad": "rad",
    "_nm": "N*m",
    "_n": "N",
    "_mm": "mm",
    "_m": "m",
    "_kg": "kg",
    "_s": "s",
    "_hz": "Hz",
    "_j": "J",
    "_v": "V",
    "_turns": "turns",
    "_index": "",
    "_count": "",
    "_ratio": "",
    "_percent": "%",
}
"""Suffix -> the unit as printed (operator checklist, plan table). Longest suffixes first: `_deg_s2`
before `_deg_s` before `_deg`, `_nm_per_deg` before `_deg`."""

_BY_LENGTH = sorted(UNIT_SUFFIXES, key=len, reverse=True)


def unit_suffix(name: str) -> str | None:
    """The unit suffix `name` ends with (the longest that matches), or None. A bare unit word
    (`nm`, `deg`) has no quantity name before it and is refused."""
    for suffix in _BY_LENGTH:
        if name.endswith(suffix) and len(name) > len(suffix):
            return suffix
    return None


_UNIT_WORDS = {"deg", "rad", "nm", "n", "mm", "m", "kg", "s", "s2", "hz", "j", "v", "per"}
"""The words units are made of: a name whose suffix is preceded by another of them (`speed_rad_s`,
`stiffness_nm_per_m`) has a compound unit that the table does not hold."""


def compound_unit_problem(name: str) -> str | None:
    """Why a quantity name that ends with a known suffix still has an unknown unit, or None: the word
    before the suffix is a unit word too (`speed_rad_s` is not rad/s, `torque_n_m` not N*m)."""
    suffix = unit_suffix(name)
    if suffix is None:
        return None
    words = name.split("_")
    stem_words = name[: -len(suffix)].split("_")
    if len(stem_words) < 2 or stem_words[-1] not in _UNIT_WORDS:
        return None
    n = 0
    while n < len(words) - 1 and words[len(words) - 1 - n] in _UNIT_WORDS:
        n += 1
    unit = "_" + "_".join(words[len(words) - n :])
    return (
        f"{name!r}: the unit {unit} is not one of the unit suffixes (it would read as {suffix}, "
        f"{UNIT_SUFFIXES[suffix] or 'a count'}); use one of: {known_suffixes()}"
    )


def unit_text(name: str) -> str:
    """The printed unit of a quantity name ("" for dimensionless or unknown)."""
    suffix = unit_suffix(name)
    return UNIT_SUFFIXES.get(suffix, "") if suffix else ""


def known_suffixes() -> str:
    """The suffixes for an error message."""
    return ", ".join(UNIT_SUFFIXES)
