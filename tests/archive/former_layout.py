"""An archive of one joint in the layout written before every group was keyed by joint, made from a fresh
archive by moving each `joints/<joint>` part up into its group, as the program wrote it before
(docs/archive.md "Several joints, and archives of one joint written before")."""

from __future__ import annotations

from pathlib import Path

import h5py

from protocol_runner.archive.checksums import seal_attributes

JOINT = "knee_flexion"
TOTALS = ("total_energy_loss_j", "total_energy_cycle_trial")


def _lift(group: h5py.Group, *, attrs: bool) -> None:
    """Move the one joint's part of `group` into it (what `group` already holds, the shared time base,
    stays), then drop the `joints` keys."""
    part = group[f"joints/{JOINT}"]
    for name in list(part):
        if name not in group:
            group.file.move(part[name].name, f"{group.name}/{name}")
    if attrs:
        for key, value in part.attrs.items():
            if key not in ("joint", "attribute_sha256") and key not in group.attrs:
                group.attrs[key] = value
    del group["joints"]
    if "joints" in group.attrs:
        del group.attrs["joints"]


def to_former_layout(path: Path) -> None:
    """Rewrite the single-joint archive `path` in the layout written before groups were keyed by joint."""
    with h5py.File(path, "r+") as f:
        for cfg in f["configurations"].values():
            for trial in cfg.get("trials", {}).values():
                for brace in ("brace_on", "brace_off"):
                    if brace in trial:
                        _lift(trial[brace], attrs=False)
            if "joints" in cfg:
                part = cfg[f"joints/{JOINT}"]
                for n, trial in part.get("trials", {}).items():
                    f.move(trial["processed"].name, f"{cfg.name}/trials/{n}/processed")
                del part["trials"]
                _lift(cfg, attrs=False)
                for name in TOTALS:
                    del cfg[name]
        for when_groups in f.get("calibration", {}).values():
            for check in when_groups.values():
                _lift(check, attrs=True)
        for comp in f.get("comparisons", {}).values():
            _lift(comp, attrs=True)
        seal_attributes(f)
