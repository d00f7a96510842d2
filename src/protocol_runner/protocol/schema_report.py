"""The protocol's `report:` section: comparisons, predictions, citations, repeatability groups."""

from __future__ import annotations

from typing import Annotated

from pydantic import BeforeValidator, Field, StrictInt, model_validator

from protocol_runner.protocol.expectations import RepeatabilitySpec
from protocol_runner.protocol.schema_base import Identifier, _Model


def _pair(value: object) -> object:
    return tuple(value) if isinstance(value, list) else value


class ComparisonSpec(_Model):
    name: Identifier
    parameter: Identifier  # a declared factor, or "trajectory" (checked in validate.py)
    section: str = ""
    title: str
    configurations: list[StrictInt] = Field(min_length=2)
    # explicit (a, b) pairs for the Differences table (b minus a), e.g. a paired design; else adjacent ones
    pairs: list[Annotated[tuple[StrictInt, StrictInt], BeforeValidator(_pair)]] | None = Field(
        default=None, min_length=1
    )

    @model_validator(mode="after")
    def _pairs_compared(self) -> ComparisonSpec:
        for a, b in self.pairs or ():
            for key in (a, b):
                if key not in self.configurations:
                    raise ValueError(
                        f"pair ({a}, {b}): configuration {key} is not in this comparison's configurations"
                    )
            if a == b:
                raise ValueError(f"pair ({a}, {b}) compares a configuration with itself")
        return self


class PredictionSpec(_Model):
    """A Bouc-Wen model fitted on configuration `fit` predicts configuration `predict` (the same device
    elements at another speed or range); the report gives the prediction's RMSE."""

    fit: StrictInt
    predict: StrictInt
    note: str = ""


class CitationsSpec(_Model):
    """Where a source (e.g. a thesis) shows what a part of the report shows: each text is printed beside
    that part ("as <text>"). All optional: a campaign that reproduces no source cites nothing."""

    configurations: str = ""  # the per-configuration loops
    comparisons: str = ""  # the overlaid loops of each comparison
    energy: str = ""  # energy per cycle against the compared factor
    reference: str = ""  # the reference datasets
    models: str = ""  # the models section as a whole
    elements: str = ""  # the elastic elements fitted to the loops' midline
    bouc_wen: str = ""  # the Bouc-Wen model against the data
    matrix: str = ""  # the test matrix
    calibration: str = ""  # the calibration step checks


class ReportSpec(_Model):
    reference_dataset: str | None = None
    citations: CitationsSpec = CitationsSpec()
    comparisons: list[ComparisonSpec] = Field(default_factory=list)
    predictions: list[PredictionSpec] = Field(default_factory=list)
    repeatability: list[RepeatabilitySpec] = Field(default_factory=list)
