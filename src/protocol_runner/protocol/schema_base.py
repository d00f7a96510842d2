"""The protocol schema's building blocks: the strict, immutable base model and the shared field types."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field


def _int_to_str(value: object) -> object:
    """Level names may be written as bare numbers in YAML (`friction: 2`): treat them as names."""
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return value


def _str_keys(value: object) -> object:
    """A mapping whose keys are level names: bare-number keys become names."""
    if isinstance(value, dict):
        return {_int_to_str(k): v for k, v in value.items()}
    return value


LevelName = Annotated[str, BeforeValidator(_int_to_str)]
Identifier = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_\-]*$", max_length=64)]


class _Model(BaseModel):
    # .inf / .nan are refused in every number field: no limit, range or time may be infinite or undefined
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _check_range(value: tuple[float, float]) -> tuple[float, float]:
    lo, hi = value
    if not lo < hi:
        raise ValueError(f"range must be [low, high] with low < high, got [{lo:g}, {hi:g}]")
    return value


RangePair = Annotated[tuple[float, float], BeforeValidator(lambda v: tuple(v) if isinstance(v, list) else v)]
