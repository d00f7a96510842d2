"""The test matrix: sets of configurations, written as explicit rows or as generators (full factorial,
one factor at a time; expanded by `protocol/generators.py`): pydantic models."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, ConfigDict, Field, StrictInt, model_validator

from protocol_runner.protocol.schema_base import Identifier, LevelName, _int_to_str, _Model, _str_keys

RESERVED_CONFIGURATION_KEYS = ("key", "run", "trajectory", "trials", "description")
MAX_KEY = 999_999  # a configuration's key and run number: ample for any matrix, and an integer every
# archive attribute, table and MATLAB field holds (a key of 10^23 passed validation, then crashed the run)


def _levels_as_str(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: (v if k in RESERVED_CONFIGURATION_KEYS else _int_to_str(v)) for k, v in data.items()}
    return data


class ConfigurationSpec(_Model):
    """An explicit row: reserved keys, and `<factor>: <level label>` for the factors it sets."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    key: StrictInt = Field(ge=1, le=MAX_KEY)
    run: StrictInt = Field(ge=1, le=MAX_KEY)
    trajectory: Identifier
    trials: StrictInt = Field(ge=1, le=50)
    description: str = ""

    @model_validator(mode="before")
    @classmethod
    def _labels(cls, data: Any) -> Any:
        data = _levels_as_str(data)
        if isinstance(data, dict):
            for k, v in data.items():
                if k not in RESERVED_CONFIGURATION_KEYS and not isinstance(v, str):
                    raise ValueError(f"{k}: a factor's level label, got {v!r}")
        return data

    @property
    def levels(self) -> dict[str, str]:
        """factor -> level label, as written."""
        return {k: str(v) for k, v in (self.model_extra or {}).items()}


LevelList = Annotated[list[LevelName], Field(min_length=1)]
LevelChoice = LevelList | Literal["all"]


class TrajectoryByLevel(_Model):
    factor: Identifier
    levels: Annotated[dict[str, Identifier], BeforeValidator(_str_keys)]


class _GeneratorSpec(_Model):
    trajectory: Identifier | None = None
    trajectory_by_level: TrajectoryByLevel | None = None
    trials: StrictInt = Field(ge=1, le=50)
    description: str = ""

    @model_validator(mode="after")
    def _one_trajectory(self) -> Any:
        if (self.trajectory is None) == (self.trajectory_by_level is None):
            raise ValueError("give exactly one of `trajectory` and `trajectory_by_level`")
        return self


class FullFactorialSpec(_GeneratorSpec):
    """Every combination of the listed factors' levels (`all` = every declared level, in declaration
    order; the LAST factor varies fastest), each with the `fixed` levels."""

    factors: Annotated[dict[Identifier, LevelChoice], Field(min_length=1)]
    fixed: Annotated[dict[Identifier, LevelName], BeforeValidator(_str_keys)] = Field(default_factory=dict)


class OneFactorAtATimeSpec(_GeneratorSpec):
    """The baseline, then each factor of `vary` set to each of its listed levels in turn (the others at
    the baseline). A listed level equal to the baseline's is skipped (the baseline is already there)."""

    baseline: Annotated[dict[Identifier, LevelName], BeforeValidator(_str_keys)] = Field(min_length=1)
    vary: Annotated[dict[Identifier, LevelList], Field(min_length=1)]
    include_baseline: bool = True


class SetSpec(_Model):
    name: Identifier
    condition: str
    configurations: list[ConfigurationSpec] = Field(default_factory=list)
    full_factorial: FullFactorialSpec | None = None
    one_factor_at_a_time: OneFactorAtATimeSpec | None = None

    @model_validator(mode="after")
    def _something(self) -> Any:
        if not self.configurations and self.full_factorial is None and self.one_factor_at_a_time is None:
            raise ValueError("a set needs `configurations`, `full_factorial` or `one_factor_at_a_time`")
        return self
