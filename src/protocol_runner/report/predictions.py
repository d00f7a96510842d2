"""Model prediction across configurations: the Bouc-Wen model fitted on one configuration
predicts another with the same device elements at another speed or range.  The pairs are declared in the
protocol (`report.predictions`); the numbers come from the archive alone: the fitted configuration's
parameters (and backbone) and the predicted configuration's centred loops stored with its own fit."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np
import yaml

from .declared import protocol_document

if TYPE_CHECKING:
    from ..models.bouc_wen.backbone import Backbone, FixedBackbone
    from ..models.bouc_wen.params import BoucWenParams


@dataclass(frozen=True)
class Prediction:
    """One declared pair's numbers. (The session unpickles these from the worker that computed them, at
    the end: this module imports the compiled model only where it runs it, not with the class.)"""

    fit_key: int
    predict_key: int
    note: str
    rmse_nm: float  # the fitted configuration's model on the predicted configuration's loops
    own_rmse_nm: float  # the predicted configuration's own fit, for scale
    reason: str = ""  # why there is no number


def declared_pairs(protocol_text: str) -> list[tuple[int, int, str]]:
    """`report.predictions` of the protocol as run (already validated when it ran)."""
    try:
        doc = protocol_document(protocol_text)
    except yaml.YAMLError:
        return []
    report = doc.get("report") if isinstance(doc, dict) else None
    items = report.get("predictions") if isinstance(report, dict) else None
    out = []
    for item in items if isinstance(items, list) else []:
        if (
            isinstance(item, dict)
            and isinstance(item.get("fit"), int)
            and isinstance(item.get("predict"), int)
        ):
            out.append((int(item["fit"]), int(item["predict"]), str(item.get("note", ""))))
    return out


def _model(g: h5py.Group) -> tuple[BoucWenParams, Backbone | FixedBackbone | None]:
    from ..models.bouc_wen.backbone import Backbone, FixedBackbone
    from ..models.bouc_wen.params import BoucWenParams

    a = g.attrs
    values = [float(a["A"]), float(a["n"]), *(float(b) for b in np.asarray(a["beta"]).ravel())]
    params = BoucWenParams.from_array(values)
    coef = np.asarray(a.get("backbone_coef", []), dtype=np.float64).ravel()
    scale = float(a.get("backbone_angle_scale_deg", math.nan))
    if str(a.get("backbone", "none")) == "polynomial" and coef.size and math.isfinite(scale):
        return params, Backbone(coef=tuple(float(c) for c in coef), angle_scale_deg=scale)
    grid = np.asarray(a.get("backbone_grid_angle_deg", []), dtype=np.float64).ravel()
    g = np.asarray(a.get("backbone_grid_torque_nm", []), dtype=np.float64).ravel()
    if str(a.get("backbone", "none")) == "elements" and grid.size >= 2 and grid.size == g.size:
        # the elements backbone as archived: sampled over its fitted angle range, held at its ends beyond
        return params, FixedBackbone(torque_nm=lambda x: np.interp(x, grid, g), kind="elements")
    return params, None


def _segments(g: h5py.Group) -> list[tuple[np.ndarray, np.ndarray]]:
    angle = np.asarray(g["angle_deg"][:], dtype=np.float64)
    torque = np.asarray(g["torque_nm"][:], dtype=np.float64)
    # archives whose fit groups predate `segment_lengths` hold one loop
    lengths = g["segment_lengths"][:] if "segment_lengths" in g else [angle.size]
    edges = np.concatenate([[0], np.cumsum(np.asarray(lengths, dtype=np.int64))])
    return [(angle[a:b], torque[a:b]) for a, b in itertools.pairwise(edges) if b - a > 2]


def predict_rmse(
    params: BoucWenParams,
    backbone: Backbone | FixedBackbone | None,
    segments: list[tuple[np.ndarray, np.ndarray]],
) -> float:
    """RMSE of the model on the given trials, each started at its own first torque (step-independent
    integration, so the stored plotting samples of the loops serve as well as every sample)."""
    from ..models.bouc_wen.simulation import simulate

    sq = 0.0
    count = 0
    for x, y in segments:
        g = backbone(x) if backbone is not None else np.zeros_like(x)
        z = g + simulate(x, params, z0=float(y[0] - g[0]))
        r = np.where(np.isfinite(z), z - y, np.nan)
        if not np.all(np.isfinite(r)):
            return math.inf  # the model diverges on this motion
        sq += float(r @ r)
        count += y.size
    return math.sqrt(sq / count) if count else math.nan


def predictions(archive: Path, protocol_text: str) -> tuple[Prediction, ...]:
    pairs = declared_pairs(protocol_text)
    if not pairs:
        return ()
    out: list[Prediction] = []
    try:
        h5 = h5py.File(archive, "r")
    except OSError:
        return ()
    with h5:
        for fit_key, predict_key, note in pairs:
            src = h5.get(f"configurations/config_{fit_key:02d}/fits/bouc_wen")
            dst = h5.get(f"configurations/config_{predict_key:02d}/fits/bouc_wen")
            if src is None or dst is None:
                missing = fit_key if src is None else predict_key
                out.append(Prediction(fit_key, predict_key, note, math.nan, math.nan, f"no fit of {missing}"))
                continue
            params, backbone = _model(src)
            rmse = predict_rmse(params, backbone, _segments(dst))
            own = float(dst.attrs.get("rmse_nm", math.nan))
            out.append(
                Prediction(fit_key, predict_key, note, rmse, own, "" if math.isfinite(rmse) else "diverges")
            )
    return tuple(out)
