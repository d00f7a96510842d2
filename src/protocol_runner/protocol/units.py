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


_PHYSICAL = ("_deg", "_rad", "_nm", "_n", "_mm", "_m", "_kg", "_s", "_hz", "_j", "_v")
"""Units that cannot precede another unit in a name: `speed_rad_s` is not rad/s (that suffix does not
exist), and `damping_nm_s_per_mrad` not N*m*s/mrad."""


def compound_unit_problem(name: str) -> str | None:
    """Why a quantity name that ends with a known suffix still has an unknown unit, or None: the part
    before the suffix ends with `_per` or with another unit (`speed_rad_s`, `torque_n_m`)."""
    suffix = unit_suffix(name)
    if suffix is None:
        return None
    stem = name[: -len(suffix)]
    before = next((u for u in _PHYSICAL if stem.endswith(u) and len(stem) > len(u)), None)
    if stem.endswith("_per") or before is not None:
        unit = name[len(stem) - len(before or "_per") :]
        return (
            f"{name!r}: the unit {unit} is not one of the unit suffixes (it would read as {suffix}, "
            f"{UNIT_SUFFIXES[suffix] or 'a count'}); use one of: {known_suffixes()}"
        )
    return None


def unit_text(name: str) -> str:
    """The printed unit of a quantity name ("" for dimensionless or unknown)."""
    suffix = unit_suffix(name)
    return UNIT_SUFFIXES.get(suffix, "") if suffix else ""


def known_suffixes() -> str:
    """The suffixes for an error message."""
    return ", ".join(UNIT_SUFFIXES)
