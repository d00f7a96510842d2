"""The archive's model-comparison groups of a configuration (or of one joint of it): `fits/element_model`
and `fits/models` (docs/archive.md; numbers from `analysis.model_comparison`), and `/predictions`."""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from ..errors import InvalidInput
from .attrs import DEVICE_JSON, JOINT
from .h5util import attr_str, put_attrs
from .paths import CONFIGURATIONS, FITS, PROCESSED
from .results import Fill

if TYPE_CHECKING:
    from ..analysis.model_comparison import ModelComparison
    from ..analysis.model_fit import ElementModelFit
    from ..models.elements import Element

ELEMENT_MODEL = "element_model"
MODELS = "models"


def element_model_attrs(fit: ElementModelFit) -> dict[str, Any]:
    est = fit.estimates
    return {
        "parameters": [f"{e.element}.{e.parameter}" for e in est],
        "value": [e.value for e in est],
        "ci95_low": [e.ci95_low for e in est],
        "ci95_high": [e.ci95_high for e in est],
        "identified": [int(e.identified) for e in est],
        "plausible_low": [e.plausible[0] for e in est],
        "plausible_high": [e.plausible[1] for e in est],
        "notes": json.dumps([e.note for e in est]),
        "covariance": [float(v) for v in np.asarray(fit.covariance).ravel()],
        "values_json": json.dumps({f"{k[0]}.{k[1]}": float(v) for k, v in fit.values.items()}),
        "rmse_nm": float(fit.rmse_nm),
        "n_samples": int(fit.n_samples),
        "n_eff": float(fit.n_eff),
    }


def models_attrs(comparison: ModelComparison) -> dict[str, Any]:
    rows = comparison.rows
    f = comparison.bouc_wen_functionals
    return {
        "model": [r.model for r in rows],
        "k": [int(r.k) for r in rows],
        "rmse_nm": [float(r.rmse_nm) for r in rows],
        "heldout_rmse_nm": [float(r.heldout_rmse_nm) for r in rows],
        "aic": [float(r.aic) for r in rows],
        "bic": [float(r.bic) for r in rows],
        "energy_model_j": [float(r.energy_model_j) for r in rows],
        "energy_data_j": [float(r.energy_data_j) for r in rows],
        "energy_flag": [int(r.energy_flag) for r in rows],
        "functional": [x.name for x in f],
        "functional_unit": [x.unit for x in f],
        "functional_value": [x.value for x in f],
        "functional_ci95_low": [x.ci95_low for x in f],
        "functional_ci95_high": [x.ci95_high for x in f],
        "bouc_wen_identified": [int(v) for v in comparison.bouc_wen_identified],
    }


def write_comparison(owner: h5py.Group, comparison: ModelComparison) -> None:
    """`fits/element_model` and `fits/models` under `owner` (a configuration group, or a joint's)."""
    fits = owner.require_group(FITS)
    if comparison.element_fit is not None:
        put_attrs(
            fits.create_group(ELEMENT_MODEL), ELEMENT_MODEL, element_model_attrs(comparison.element_fit)
        )
    put_attrs(fits.create_group(MODELS), MODELS, models_attrs(comparison))


def strings(g: h5py.Group, key: str) -> list[str]:
    """A list-of-strings attribute written by `write_comparison` (stored as a JSON list)."""
    value = g.attrs.get(key, "[]")
    value = value.decode("utf-8") if isinstance(value, bytes) else value
    if isinstance(value, str):
        out = json.loads(value) if value.startswith("[") else [value]
        return [str(v) for v in out]
    return [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in np.atleast_1d(value)]


def _list(g: h5py.Group, key: str) -> list[Any]:
    return [float(v) for v in np.atleast_1d(np.asarray(g.attrs.get(key, []), dtype=np.float64))]


#: The numbers of each model a `fits/models` group holds, after its name (models.csv's columns).
MODEL_VALUES = ("k", "rmse_nm", "heldout_rmse_nm", "aic", "bic", "energy_model_j", "energy_data_j")


def read_models(g: h5py.Group) -> list[list[Any]]:
    """The rows of a `fits/models` group, one per model: its name, then its `MODEL_VALUES`."""
    k, *values = (_list(g, c) for c in MODEL_VALUES)
    return [[m, int(k[i]), *(v[i] for v in values)] for i, m in enumerate(strings(g, "model"))]


def read_element_model(g: h5py.Group) -> list[list[Any]]:
    """The rows of a `fits/element_model` group: element, parameter, value, interval, identified, note
    (empty where an archive records none)."""
    value, low, high, ident = (_list(g, k) for k in ("value", "ci95_low", "ci95_high", "identified"))
    names = strings(g, "parameters")
    notes = strings(g, "notes")
    return [
        [
            *str(p).rsplit(".", 1),
            value[i],
            low[i],
            high[i],
            bool(ident[i]),
            notes[i] if i < len(notes) else "",
        ]
        for i, p in enumerate(names)
    ]


Device = list[tuple[str, str, dict[str, object]]]


def archived_device(cfg: h5py.Group) -> Device:
    """The configuration's device as the session resolved it (its `device_json` attribute, docs/archive.md):
    (name, type, parameters) per element; empty for an archive written before devices were declared (its
    element fit is then not applicable). A `device_json` that is not the documented list is named."""
    if DEVICE_JSON not in cfg.attrs:
        return []
    where = f"{cfg.file.filename}: {cfg.name}@{DEVICE_JSON}"
    try:
        doc = json.loads(attr_str(cfg, DEVICE_JSON, "[]"))
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{where}: not valid JSON ({exc.msg})") from None
    if not isinstance(doc, list) or not all(isinstance(e, dict) and "name" in e and "type" in e for e in doc):
        raise InvalidInput(f"{where}: must be a JSON list of elements, each with a name and a type")
    return [(str(e.pop("name")), str(e.pop("type")), e) for e in doc]


def joint_device(device: Device, joint: str) -> Device:
    """The elements of an archived device that `joint` carries (those naming no joint or that joint; every
    element when `joint` is ""), without their `joint` parameter."""
    return [
        (n, t, {k: v for k, v in p.items() if k != JOINT})
        for n, t, p in device
        if not joint or p.get(JOINT, "") in ("", joint)
    ]


def stored_device(cfg: h5py.Group, joint: str = "") -> tuple[Element, ...]:
    """The device a configuration group declares (`archived_device`), or the elements one joint of it
    carries (`joint_device`); empty when it declares none."""
    from ..models.elements import build_device

    return build_device(joint_device(archived_device(cfg), joint))


def read_processed_trials(trials: h5py.Group) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Each trial's stored processed `(time_s, angle_deg, brace_torque_nm)` under a `trials` group, in
    trial order: the element model's input (it needs the time for the speed)."""
    out = []
    for n in sorted(trials, key=int):
        g = trials[n][PROCESSED]
        out.append(
            tuple(np.asarray(g[k][()], dtype=np.float64) for k in ("time_s", "angle_deg", "brace_torque_nm"))
        )
    return out  # type: ignore[return-value]


def comparison_fill(name: str, before: Fill, comparison: ModelComparison) -> Fill:
    """`before` (the Bouc-Wen fit's fill), then the comparison's groups under `configurations/<name>`."""

    def fill(f: h5py.File) -> None:
        before(f)
        write_comparison(f.require_group(f"{CONFIGURATIONS}/{name}"), comparison)

    return fill


PREDICTIONS = "predictions"


def write_predictions(f: h5py.File, rows: list[dict[str, Any]]) -> None:
    """(Re)write `/predictions`: one group `from_<A>_to_<B>` (with `_<joint>` for one joint of a
    several-joint configuration) per declared prediction, its numbers as attributes (`prediction` in
    `attrs.ATTRIBUTES`; absent where a number does not exist)."""
    if PREDICTIONS in f:
        del f[PREDICTIONS]
    root = f.create_group(PREDICTIONS)
    for row in rows:
        name = f"from_{row['fit_configuration']}_to_{row['predict_configuration']}"
        name += f"_{row['joint']}" if row["joint"] else ""
        kept = {k: v for k, v in row.items() if not (isinstance(v, float) and not math.isfinite(v))}
        put_attrs(root.require_group(name), "prediction", kept)
