"""`--reprocess` of a multi-joint configuration (docs/archive.md "Several joints"): each joint's raw
trials (`trials/<n>/brace_<b>/joints/<joint>`) through the function the session's processing and fit steps
use (`analysis.service.analyse_joints`), written by the same writers under `joints/<joint>/`, with the
leg's total energy per cycle."""

from __future__ import annotations

from collections.abc import Sequence

import h5py

from ..analysis.pipeline import TrialPair
from ..analysis.processing_settings import ProcessingSettings
from ..analysis.service import BoucWenSettings, analyse_joints
from ..errors import InvalidInput
from .attrs import JOINTS as JOINTS_ATTR
from .attrs import STATUS
from .h5util import attr_str, attr_strs, put
from .model_results import compare_owner
from .paths import JOINTS, PROCESSED, TRIALS, joint_path
from .results import bouc_wen_fill, processed_fill, read_recording

Device = list[tuple[str, str, dict[str, object]]]


def complete_pairs(cfg: h5py.Group, name: str, joint: str | None = None) -> list[TrialPair]:
    """The raw trial pairs of configuration group `cfg` (of one `joint` of a multi-joint one), without
    the trials a board failure cut short; stale `processed` groups are removed. A trial whose raw data
    lack a dataset is named."""
    pairs = []
    trials = cfg[TRIALS]
    where = "" if joint is None else joint_path("", joint)
    for n in sorted(trials, key=int):
        g = trials[n]
        if PROCESSED in g:
            del g[PROCESSED]
        braces = ("brace_on", "brace_off")
        if not all(b in g and attr_str(g[b], STATUS, "complete") == "complete" for b in braces):
            continue
        try:
            on, off = (read_recording(g[b + where]) for b in braces)
            pairs.append(TrialPair(on, off, trial=int(n)))
        except KeyError as exc:
            who = "" if joint is None else f" ({joint})"
            raise InvalidInput(
                f"{name}/{TRIALS}/{n}{who}: the raw data lack {exc}; cannot reprocess"
            ) from None
    return pairs


def joint_device(device: Device, joint: str) -> Device:
    """The elements of a multi-joint device that `joint` carries, without their `joint` parameter."""
    return [
        (n, t, {k: v for k, v in p.items() if k != "joint"}) for n, t, p in device if p.get("joint") == joint
    ]


def reprocess_joints(
    f: h5py.File,
    name: str,
    device: Device,
    settings: ProcessingSettings,
    fit: BoucWenSettings | None,
    *,
    elements: bool,
) -> None:
    """Redo one multi-joint configuration's processing in `f` (its old results removed first), and the
    Bouc-Wen fit (`fit`, None when off) of each joint carrying elements of the archived `device`;
    `elements`: whether the element fit is on."""
    cfg = f["configurations"][name]
    joints = attr_strs(cfg, JOINTS_ATTR)
    for stale in (JOINTS, "total_energy_loss_j", "total_energy_cycle_trial"):
        if stale in cfg:
            del cfg[stale]
    recordings: list[tuple[str, Sequence[TrialPair]]] = []
    for joint in joints:
        pairs = complete_pairs(cfg, name, joint)
        if not pairs:
            return
        recordings.append((joint, pairs))
    analysis = analyse_joints(
        recordings,
        settings,
        fit,
        devices={j: (joint_device(device, j) or None) if elements else None for j in joints},
        fitted_joints=sorted({str(p.get("joint")) for _, _, p in device}),
    )
    for joint, one in zip(analysis.joints, analysis.analyses, strict=True):
        processed_fill(joint_path(name, joint), one, settings)(f)
        if one.bouc_wen is not None:
            bouc_wen_fill(joint_path(name, joint), one.bouc_wen)(f)
            if elements:  # the model comparison of the joint, as the fit step makes it
                compare_owner(cfg[f"{JOINTS}/{joint}"], joint_device(device, joint), one.bouc_wen)
    put(cfg, "total_energy_loss_j", analysis.total_energy_loss_j, "J")
    put(cfg, "total_energy_cycle_trial", analysis.total_energy_cycle_trial, "1")
