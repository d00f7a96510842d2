"""Booleans where the schema wants numbers: YAML reads `yes`, `no`, `on`, `off`, `true` and `false` as
booleans, and pydantic takes one for 1 or 0 in a number field (`periods: yes` became 1 period). After a
file validates, `boolean_numbers` walks the validated model beside the file's data and names every number
field (alone, or an item of its list or mapping) the file gave a boolean, so the loader refuses it with the
field's line. Fields that may hold a boolean (`enabled: true`) are left alone."""

from __future__ import annotations

from typing import Any, get_args

from pydantic import BaseModel

from .loaded import Loc

MESSAGE = "expected a number, got {value!r} (YAML reads yes, no, on, off, true and false as booleans)"


def boolean_numbers(model: BaseModel, data: object, loc: Loc = ()) -> list[tuple[Loc, str]]:
    """(location, message) of every number field of `model` (and of the models inside it) that `data`,
    the mapping it was validated from, gives as a boolean."""
    if not isinstance(data, dict):
        return []
    out: list[tuple[Loc, str]] = []
    for name, field in type(model).model_fields.items():
        key = field.alias or name
        if key not in data:
            continue
        raw, value, here = data[key], getattr(model, name), (*loc, key)
        if _numbers_not_booleans(field.annotation):
            out += [(where, MESSAGE.format(value=b)) for where, b in _booleans(raw, here)]
        else:
            out += _inside(value, raw, here)
    return out


def _inside(value: object, raw: object, loc: Loc) -> list[tuple[Loc, str]]:
    """The models held by a field's value (a model, or a list or mapping of them), each against its data."""
    if isinstance(value, BaseModel):
        return boolean_numbers(value, raw, loc)
    out: list[tuple[Loc, str]] = []
    if isinstance(value, list | tuple) and isinstance(raw, list) and len(raw) == len(value):
        for i, (v, r) in enumerate(zip(value, raw, strict=True)):
            out += _inside(v, r, (*loc, i))
    elif isinstance(value, dict) and isinstance(raw, dict):
        by_text = {str(k): k for k in raw}
        for k, v in value.items():
            if str(k) in by_text:
                out += _inside(v, raw[by_text[str(k)]], (*loc, str(k)))
    return out


def _booleans(raw: object, loc: Loc) -> list[tuple[Loc, bool]]:
    if isinstance(raw, bool):
        return [(loc, raw)]
    if isinstance(raw, list):
        return [((*loc, i), v) for i, v in enumerate(raw) if isinstance(v, bool)]
    if isinstance(raw, dict):
        return [((*loc, str(k)), v) for k, v in raw.items() if isinstance(v, bool)]
    return []


def _kinds(annotation: object) -> set[object]:
    """The plain types an annotation is made of (through unions, Annotated, containers; a Literal's
    booleans count as bool)."""
    out: set[object] = {annotation} if isinstance(annotation, type) or annotation is Any else set()
    if isinstance(annotation, bool):
        out.add(bool)
    for arg in get_args(annotation):
        out |= _kinds(arg)
    return out


def _numbers_not_booleans(annotation: object) -> bool:
    """Whether a field of this annotation holds plain numbers (no booleans, no models, nothing at all)."""
    kinds = _kinds(annotation)
    if kinds & {bool, Any, object} or any(isinstance(k, type) and issubclass(k, BaseModel) for k in kinds):
        return False
    return bool(kinds & {float, int})
