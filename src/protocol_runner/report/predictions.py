"""Model prediction across configurations (docs/analysis.md "Prediction across configurations"), from
the archive alone: configuration B predicted by the element model and by the Bouc-Wen model fitted on A,
for the pairs the protocol declares (`report.predictions`); where B's angles reach beyond A's by more than
EXTRAPOLATION_SHARE of A's span, the prediction extrapolates and says so."""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from ..archive.model_results import stored_device, strings
from ..archive.paths import joint_groups
from ..protocol.schema import PredictionSpec
from .declared import declared_entries

if TYPE_CHECKING:
    from ..models.bouc_wen.backbone import Backbone, FixedBackbone
    from ..models.bouc_wen.params import BoucWenParams


EXTRAPOLATION_SHARE = 0.05
"""B's angles may reach this share of A's fitted span beyond it before a prediction extrapolates (a degree
or two is a loop's ordinary reach from one configuration to the next)."""


@dataclass(frozen=True)
class AngleRanges:
    """The angles (deg, (low, high)) a model was fitted on, configuration A's, and those it predicts, B's."""

    source_deg: tuple[float, float]
    target_deg: tuple[float, float]

    @property
    def beyond_source_deg(self) -> float:
        """How far B's angles reach beyond A's, on the side where they reach farther (0 within A's)."""
        (a_low, a_high), (b_low, b_high) = self.source_deg, self.target_deg
        return float(max(0.0, a_low - b_low, b_high - a_high))

    @property
    def extrapolated(self) -> bool:
        """B's angles reach beyond A's by more than EXTRAPOLATION_SHARE of A's span."""
        a_low, a_high = self.source_deg
        return self.beyond_source_deg > EXTRAPOLATION_SHARE * (a_high - a_low)


def angle_range(angles: list[np.ndarray]) -> tuple[float, float]:
    """(lowest, highest) of the angles of all the given trials (deg)."""
    both = np.concatenate([np.asarray(a, dtype=np.float64).ravel() for a in angles])
    return float(np.min(both)), float(np.max(both))


@dataclass(frozen=True)
class Prediction:
    """One declared pair's numbers (unpickled by the session from the worker that computed them: the
    compiled model is imported only where it runs)."""

    fit_key: int
    predict_key: int
    note: str
    rmse_nm: float  # the fitted configuration's Bouc-Wen model on the predicted configuration's loops
    own_rmse_nm: float  # the predicted configuration's own Bouc-Wen fit, for scale
    reason: str = ""  # why there is no Bouc-Wen number
    element: ElementPrediction | None = None  # the element model's prediction, when A has one
    figure: str = ""  # B's measured loop and the element model's prediction (a PNG data URI), when drawn
    joint: str = ""  # the joint whose data both models were fitted to and predict
    bouc_wen_ranges: AngleRanges | None = None  # A's and B's centred loop angles, when both were fitted

    @property
    def extrapolation_note(self) -> str:
        """A sentence naming each model that runs beyond the angles it was fitted on, and by how much,
        with what that means for it; empty when neither does."""
        e = self.element.ranges if self.element is not None else None
        said = [
            f"the {name} runs {r.beyond_source_deg:.1f} deg beyond the angles it was fitted on ({where}: "
            f"{_range_text(r.source_deg)} on {self.fit_key}, {_range_text(r.target_deg)} on {self.predict_key})"
            for name, where, r in (
                ("element model", "joint angle", e),
                ("Bouc-Wen model", "centred angle", self.bouc_wen_ranges),
            )
            if r is not None and r.extrapolated
        ]
        if not said:
            return ""
        text = (
            f"Configuration {self.predict_key} predicted from {self.fit_key} extrapolates: {'; '.join(said)}."
        )
        if self.bouc_wen_ranges is not None and self.bouc_wen_ranges.extrapolated:
            rmse = (
                f"its RMSE of {self.rmse_nm:.2f} N·m ({self.predict_key}'s own fit: {self.own_rmse_nm:.2f} N·m)"
                if math.isfinite(self.rmse_nm)
                else "its prediction"
            )
            text += (
                f" The Bouc-Wen backbone is a polynomial fitted on {self.fit_key}'s angles and is not meant to"
                f" extrapolate: {rmse} is what the polynomial does outside them, not a measure of the model on"
                " the angles it was fitted on."
            )
        if self.element is not None and e is not None and e.extrapolated:
            text += (
                " The element model is physical (the declared elements with their geometry), so it carries"
                f" over to angles outside those it was fitted on (its RMSE: {self.element.rmse_nm:.2f} N·m)."
            )
        return text


@dataclass(frozen=True)
class ElementPrediction:
    """The element model fitted on A run on B's motion (module docstring)."""

    rmse_nm: float
    energy_predicted_j: float
    energy_predicted_ci95_low_j: float
    energy_predicted_ci95_high_j: float
    energy_measured_j: float
    angle_deg: np.ndarray  # B's first trial: angle, measured and predicted torque (the overlay)
    measured_torque_nm: np.ndarray
    predicted_torque_nm: np.ndarray
    ranges: AngleRanges | None = None  # A's processed joint angles (the fit's) and B's (the prediction's)


def _range_text(r: tuple[float, float]) -> str:
    return f"[{r[0]:.1f}, {r[1]:.1f}] deg"


PREDICTION_DRAWS = 100
OVERLAY_POINTS = 1500


def declared_pairs(protocol_text: str) -> list[tuple[int, int, str]]:
    """`report.predictions` of the protocol as run (validated when it ran; an invalid entry is left out)."""
    specs, _ = declared_entries(protocol_text, ("report", "predictions"), PredictionSpec)
    return [(s.fit, s.predict, s.note) for s in specs]


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
    """RMSE of the model on the given trials, each started at its own first torque (the integration is
    step-independent: the stored plotting samples serve as well as every sample)."""
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


def reproducibility(configs: h5py.Group, archive_joints: str) -> dict[tuple[str, str], float]:
    """Per fitted parameter, the standard deviation of its fitted value across the configurations that
    declare the same value for it (pooled over the declared values shared by two or more): how far the same
    setting lands from one configuration to the next, beyond a configuration's own fit uncertainty."""
    from ..models.element_model import layout

    groups: dict[tuple[tuple[str, str], float], list[float]] = {}
    parts = [
        (configs[name], joint, part)
        for name in configs
        for joint, part in joint_groups(configs[name], archive_joints)
    ]
    for cfg, joint, part in parts:
        g = part.get("fits/element_model")
        if g is None or "device_json" not in cfg.attrs:
            continue
        declared = layout(stored_device(cfg, joint)).declared
        fitted = json.loads(str(g.attrs["values_json"]))
        for key in strings(g, "parameters"):
            element, param = key.rsplit(".", 1)
            k = (element, param)
            if k in declared and key in fitted:
                groups.setdefault((k, declared[k]), []).append(float(fitted[key]))
    sq: dict[tuple[str, str], float] = {}
    dof: dict[tuple[str, str], int] = {}
    for (k, _), values in groups.items():
        if len(values) >= 2:
            v = np.asarray(values)
            sq[k] = sq.get(k, 0.0) + float(np.sum((v - v.mean()) ** 2))
            dof[k] = dof.get(k, 0) + v.size - 1
    return {k: math.sqrt(sq[k] / dof[k]) for k in sq}


def element_prediction(
    src: h5py.Group,
    dst: h5py.Group,
    spread: dict[tuple[str, str], float],
    joint: str,
    src_part: h5py.Group,
    dst_part: h5py.Group,
) -> ElementPrediction | None:
    """The element model fitted on configuration group `src` predicting configuration group `dst`, for
    `joint` (its part of each group: `src_part`, `dst_part`); None when `src` has no element model or
    either has no declared device."""
    from ..analysis.model_comparison import motions_of
    from ..analysis.model_fit import mean_energy_j
    from ..archive.model_results import read_processed_trials
    from ..models.element_model import layout, model_torque_nm, transfer

    g = src_part.get("fits/element_model")
    if (
        g is None
        or "device_json" not in src.attrs
        or "device_json" not in dst.attrs
        or "trials" not in dst_part
    ):
        return None
    values = {tuple(k.rsplit(".", 1)): float(v) for k, v in json.loads(str(g.attrs["values_json"])).items()}
    names = [(p.rsplit(".", 1)[0], p.rsplit(".", 1)[1]) for p in strings(g, "parameters")]
    x = np.asarray(g.attrs["value"], dtype=np.float64).ravel()
    cov = np.asarray(g.attrs["covariance"], dtype=np.float64).reshape(x.size, x.size)
    # the configuration-to-configuration spread of each parameter adds to A's own fit uncertainty
    cov = cov + np.diag(np.array([spread.get(k, 0.0) ** 2 for k in names]))
    lay_a, lay_b = layout(stored_device(src, joint)), layout(stored_device(dst, joint))
    trials_b = read_processed_trials(dst_part["trials"])
    motions = motions_of(trials_b)
    ranges = None
    if "trials" in src_part:
        fitted_angles = [angle for _, angle, _ in read_processed_trials(src_part["trials"])]
        ranges = AngleRanges(angle_range(fitted_angles), angle_range([angle for _, angle, _ in trials_b]))

    def run(fitted: dict) -> list[np.ndarray]:
        vb = transfer(lay_a, lay_b, fitted)
        return [model_torque_nm(lay_b, vb, m) for m in motions]

    predicted = run(values)
    r = np.concatenate([(p - m.torque_nm)[m.settled :] for p, m in zip(predicted, motions, strict=True)])
    energy = mean_energy_j(motions, predicted)
    low = high = math.nan
    if x.size and np.all(np.isfinite(cov)):
        rng = np.random.default_rng(0)
        draws = rng.multivariate_normal(x, cov, size=PREDICTION_DRAWS, check_valid="ignore")
        energies = [
            mean_energy_j(motions, run({**values, **dict(zip(names, d, strict=True))})) for d in draws
        ]
        low, high = (float(v) for v in np.nanpercentile(energies, [2.5, 97.5]))
    first = motions[0]
    stride = max(1, first.angle_deg.size // OVERLAY_POINTS)
    return ElementPrediction(
        rmse_nm=float(np.sqrt(np.mean(r * r))) if r.size else math.nan,
        energy_predicted_j=energy,
        energy_predicted_ci95_low_j=low,
        energy_predicted_ci95_high_j=high,
        energy_measured_j=mean_energy_j(motions, [m.torque_nm for m in motions]),
        angle_deg=first.angle_deg[::stride],
        measured_torque_nm=first.torque_nm[::stride],
        predicted_torque_nm=predicted[0][::stride],
        ranges=ranges,
    )


def predictions(archive: Path, protocol_text: str, *, figures: bool = True) -> tuple[Prediction, ...]:
    """The declared predictions of `archive`, each with its figure (`report.figures.prediction_figure`) when
    `figures` and the element model predicted it."""
    made = _predictions(archive, protocol_text)
    if not figures or not any(p.element is not None for p in made):
        return made
    from .figures import prediction_figure  # matplotlib: only where the figures are drawn

    def drawn(p: Prediction, e: ElementPrediction | None) -> Prediction:
        if e is None:
            return p
        fitted = e.ranges.source_deg if e.ranges is not None else None
        figure = prediction_figure(
            p.fit_key, p.predict_key, e.angle_deg, e.measured_torque_nm, e.predicted_torque_nm, fitted
        )
        return replace(p, figure=figure)

    return tuple(drawn(p, p.element) for p in made)


def _predictions(archive: Path, protocol_text: str) -> tuple[Prediction, ...]:
    pairs = declared_pairs(protocol_text)
    if not pairs:
        return ()
    out: list[Prediction] = []
    try:
        h5 = h5py.File(archive, "r")
    except OSError:
        return ()
    with h5:
        joints = str(h5.attrs.get("joint", ""))
        spread = reproducibility(h5["configurations"], joints) if "configurations" in h5 else {}
        for fit_key, predict_key, note in pairs:
            cfg_a = h5.get(f"configurations/config_{fit_key:02d}")
            cfg_b = h5.get(f"configurations/config_{predict_key:02d}")
            if cfg_a is None or cfg_b is None:
                missing = fit_key if cfg_a is None else predict_key
                out.append(Prediction(fit_key, predict_key, note, math.nan, math.nan, f"no fit of {missing}"))
                continue
            parts_b = dict(joint_groups(cfg_b, joints))
            parts_a = joint_groups(cfg_a, joints)
            for name, part_a in parts_a:
                joint = name if len(parts_a) > 1 else ""  # named where the configuration has several
                part_b = parts_b.get(name)
                element = None
                if part_b is not None:
                    element = element_prediction(cfg_a, cfg_b, spread, name, part_a, part_b)
                src = part_a.get("fits/bouc_wen")
                dst = part_b.get("fits/bouc_wen") if part_b is not None else None
                rmse = own = math.nan
                ranges = None
                if src is None or dst is None:
                    reason = f"no fit of {fit_key if src is None else predict_key}"
                else:
                    segments = _segments(dst)
                    rmse = predict_rmse(*_model(src), segments)
                    own = float(dst.attrs.get("rmse_nm", math.nan))
                    reason = "" if math.isfinite(rmse) else "diverges"
                    fitted_on = [x for x, _ in _segments(src)]
                    if fitted_on and segments:
                        ranges = AngleRanges(angle_range(fitted_on), angle_range([x for x, _ in segments]))
                out.append(
                    Prediction(
                        fit_key,
                        predict_key,
                        note,
                        rmse,
                        own,
                        reason,
                        element,
                        joint=joint,
                        bouc_wen_ranges=ranges,
                    )
                )
    return tuple(out)


def prediction_row(p: Prediction) -> dict[str, object]:
    """A prediction's numbers as `/predictions` stores them (`archive.model_results.write_predictions`)."""
    e = p.element
    energies = ("energy_predicted_j", "energy_predicted_ci95_low_j", "energy_predicted_ci95_high_j")
    return {
        "fit_configuration": p.fit_key,
        "predict_configuration": p.predict_key,
        "joint": p.joint,
        "note": p.note,
        "element_rmse_nm": e.rmse_nm if e else math.nan,
        **{name: getattr(e, name) if e else math.nan for name in (*energies, "energy_measured_j")},
        "bouc_wen_rmse_nm": p.rmse_nm,
        "bouc_wen_own_rmse_nm": p.own_rmse_nm,
        "reason": p.reason,
        **_ranges_row("element", e.ranges if e else None),
        **_ranges_row("bouc_wen", p.bouc_wen_ranges),
    }


def _ranges_row(model: str, r: AngleRanges | None) -> dict[str, object]:
    return {
        f"{model}_source_range_deg": list(r.source_deg) if r else None,
        f"{model}_target_range_deg": list(r.target_deg) if r else None,
        f"{model}_beyond_source_deg": r.beyond_source_deg if r else math.nan,
        f"{model}_extrapolated": r.extrapolated if r else None,
    }


def record_predictions(archive: Path, made: tuple[Prediction, ...] | None = None) -> int:
    """(Re)write the archive's `/predictions` from its declared pairs (`made`: already computed from this
    archive); return how many. Nothing is written for an archive that declares none."""
    from ..archive.model_results import write_predictions

    if made is None:
        from .h5read import scalar_str

        with h5py.File(archive, "r") as h5:
            text = scalar_str(h5["protocol"]) if "protocol" in h5 else ""
        made = predictions(archive, text, figures=False)
    if not made:
        return 0
    with h5py.File(archive, "a") as h5:
        write_predictions(h5, [prediction_row(p) for p in made])
    return len(made)
