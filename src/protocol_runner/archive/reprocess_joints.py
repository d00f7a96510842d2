"""`--reprocess` of a multi-joint configuration (docs/archive.md "Several joints"): each joint's raw
trials (`trials/<n>/brace_<b>/joints/<joint>`) through the same pipeline the session's processing step
used, written by the same writer under `joints/<joint>/`, and the leg's total energy per cycle."""

from __future__ import annotations

import h5py
import numpy as np

from ..analysis.joint_energy import total_energy_per_cycle
from ..analysis.loops import centred_loop, fit_loops
from ..analysis.pipeline import (
    ConfigurationResult,
    ProcessingSettings,
    Recording,
    TrialPair,
    process_configuration,
)
from ..errors import InvalidInput
from ..protocol.schema import BoucWenFitSpec
from .h5util import attr_str, put
from .results import bouc_wen_fill, processed_fill


def _recording(g: h5py.Group) -> Recording:
    return Recording(
        time_s=g["time_s"][:],
        angle_deg=g["angle_deg"][:],
        torque_nm=g["torque_nm"][:],
        command_deg=g["command_deg"][:],
        command_time_s=g["command_time_s"][:],
    )


def reprocess_joints(
    f: h5py.File,
    name: str,
    device: list[tuple[str, str, dict[str, object]]] | None,
    settings: ProcessingSettings,
    bouc_wen: BoucWenFitSpec,
    fit_joints: list[str],
) -> None:
    """Redo one multi-joint configuration's processing in `f` (its old results removed first), and the
    Bouc-Wen fit of each joint in `fit_joints` (those carrying elements) when `bouc_wen.enabled`."""
    cfg = f["configurations"][name]
    joints = [j.decode() if isinstance(j, bytes) else str(j) for j in np.atleast_1d(cfg.attrs["joints"])]
    for stale in ("joints", "total_energy_loss_j", "total_energy_cycle_trial"):
        if stale in cfg:
            del cfg[stale]
    trials = cfg.get("trials", {})
    results: list[ConfigurationResult] = []
    for joint in joints:
        pairs = []
        for n in sorted(trials, key=int):
            g = trials[n]
            if not all(
                b in g and attr_str(g[b], "status", "complete") == "complete"
                for b in ("brace_on", "brace_off")
            ):
                continue
            try:
                pairs.append(
                    TrialPair(
                        _recording(g[f"brace_on/joints/{joint}"]),
                        _recording(g[f"brace_off/joints/{joint}"]),
                        trial=int(n),
                    )
                )
            except KeyError as exc:
                raise InvalidInput(
                    f"{name}/trials/{n} ({joint}): the raw data lack {exc}; cannot reprocess"
                ) from None
        if not pairs:
            return
        own = None
        if device is not None:
            own = [
                (n, t, {k: v for k, v in p.items() if k != "joint"})
                for n, t, p in device
                if p.get("joint") == joint
            ]
        results.append(process_configuration(pairs, settings, device=own or None))
        processed_fill(f"{name}/joints/{joint}", results[-1], settings)(f)
        if bouc_wen.enabled and joint in fit_joints:  # as the session: on the stored (200 Hz) loops
            stored = cfg[f"joints/{joint}/trials"]
            raw = [
                (
                    stored[str(t.trial)]["processed/angle_deg"][:],
                    stored[str(t.trial)]["processed/brace_torque_nm"][:],
                )
                for t in results[-1].trials
            ]
            segments = [centred_loop(a, t) for a, t in raw]
            bw, cv = fit_loops(
                segments,
                starts=bouc_wen.starts,
                cross_validated=bouc_wen.cross_validate,
                backbone_degree=bouc_wen.polynomial_degree,
                elements=(raw, own or None) if bouc_wen.backbone == "elements" else None,
            )
            bouc_wen_fill(f"{name}/joints/{joint}", bw, segments, cv)(f)
    total, which = total_energy_per_cycle(
        [r.energy_loss_j for r in results], [r.energy_cycle_trial for r in results]
    )
    put(cfg, "total_energy_loss_j", total, "J")
    put(cfg, "total_energy_cycle_trial", which, "1")
