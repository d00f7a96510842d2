"""The model tables of `--export` (docs/report.md): `models.csv`, `elements.csv` and `predictions.csv`.

`models.csv`: one row per configuration, joint and model (`elements`, `dahl`, `bouc_wen`) from
`fits/models`: configuration, joint, model, k, rmse_nm, heldout_rmse_nm, aic, bic, energy_model_j,
energy_data_j (`analysis.model_comparison`).

`elements.csv`: one row per fitted element parameter from `fits/element_model`: configuration, joint,
element, parameter, value, ci95_low, ci95_high, identified (`analysis.model_fit`; the brakes appear once,
as their sum, e.g. element `brake+hinge`).

`predictions.csv`: one row per declared `report.predictions` pair and model: from_configuration,
to_configuration, joint, model, rmse_nm, energy_predicted_j, energy_predicted_ci95_low_j,
energy_predicted_ci95_high_j, energy_measured_j (`report.predictions`; the Bouc-Wen row has its RMSE only).

The `joint` column names the joint of each row, as in the other tables of `--export` (`report.tidy`); a
prediction's is the archive's joint (predictions are made for a single joint).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path

import h5py

from ..archive.model_results import read_element_model, read_models
from ..archive.paths import joint_groups
from .h5read import attr_str

MODEL_COLUMNS = (
    "configuration",
    "joint",
    "model",
    "k",
    "rmse_nm",
    "heldout_rmse_nm",
    "aic",
    "bic",
    "energy_model_j",
    "energy_data_j",
)
ELEMENT_COLUMNS = (
    "configuration",
    "joint",
    "element",
    "parameter",
    "value",
    "ci95_low",
    "ci95_high",
    "identified",
)
PREDICTION_COLUMNS = (
    "from_configuration",
    "to_configuration",
    "joint",
    "model",
    "rmse_nm",
    "energy_predicted_j",
    "energy_predicted_ci95_low_j",
    "energy_predicted_ci95_high_j",
    "energy_measured_j",
)


def _owners(h5: h5py.File) -> Iterator[tuple[int, str, h5py.Group]]:
    """(configuration key, joint, group holding `fits`) of every configuration and joint."""
    configs = h5.get("configurations")
    if not isinstance(configs, h5py.Group):
        return
    archive_joints = attr_str(h5.attrs, "joint")
    for name in sorted(configs):
        cfg = configs[name]
        key = int(cfg.attrs.get("key", int(name.rsplit("_", 1)[-1])))
        for joint, group in joint_groups(cfg, archive_joints):
            yield key, joint, group


Table = tuple[str, Sequence[str], list[list[object]]]


def model_tables(archive: Path, protocol_text: str) -> tuple[Table, ...]:
    """The rows of models.csv, elements.csv and predictions.csv of `archive`, each as (file name, columns,
    rows); `report.tidy` writes them beside the other tables (a number that does not exist is NaN)."""
    from .predictions import predictions

    models: list[list[object]] = []
    elements: list[list[object]] = []
    with h5py.File(archive, "r") as h5:
        archive_joint = attr_str(h5.attrs, "joint").split(",")[0].strip()
        for key, joint, owner in _owners(h5):
            if "fits/models" in owner:
                for row in read_models(owner["fits/models"]):
                    models.append([key, joint, *(row[c] for c in MODEL_COLUMNS[2:])])
            if "fits/element_model" in owner:
                for row in read_element_model(owner["fits/element_model"]):
                    elements.append([key, joint, *(row[c] for c in ELEMENT_COLUMNS[2:])])
    rows: list[list[object]] = []
    for p in predictions(archive, protocol_text, figures=False):
        e = p.element
        if e is not None:
            rows.append(
                [
                    p.fit_key,
                    p.predict_key,
                    p.joint or archive_joint,
                    "elements",
                    e.rmse_nm,
                    e.energy_predicted_j,
                    e.energy_predicted_ci95_low_j,
                    e.energy_predicted_ci95_high_j,
                    e.energy_measured_j,
                ]
            )
        rows.append(
            [
                p.fit_key,
                p.predict_key,
                p.joint or archive_joint,
                "bouc_wen",
                p.rmse_nm,
                math.nan,
                math.nan,
                math.nan,
                math.nan,
            ]
        )
    return (
        ("models.csv", MODEL_COLUMNS, models),
        ("elements.csv", ELEMENT_COLUMNS, elements),
        ("predictions.csv", PREDICTION_COLUMNS, rows),
    )
